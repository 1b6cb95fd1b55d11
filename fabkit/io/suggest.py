""""Did you mean": the nearest valid names to a misspelt one (commands, options, templates,
formats, methods, settings), for the one-line errors."""

from __future__ import annotations

import difflib

__all__ = ["close_names", "did_you_mean", "nearest_file"]

#: How alike a name must be to be offered (difflib's ratio; 0.6 is its own default).
CUTOFF = 0.6


def close_names(word, choices, n: int = 3) -> list[str]:
    """The valid names closest to ``word``, best first (at most ``n``; none when nothing is
    alike). A difference of case alone is found too (``network`` → ``NETWORK``).

    Examples
    --------
    >>> close_names("exprot", ["bench", "export", "fold", "info"])
    ['export']
    >>> close_names("zzz", ["export"])
    []
    """
    word = str(word)
    choices = [str(c) for c in choices if str(c) != word]  # the word itself helps no one
    if not word or not choices:
        return []
    same_case = [c for c in choices if c.lower() == word.lower() and c != word]
    close = difflib.get_close_matches(word, choices, n=n, cutoff=CUTOFF)
    folded = {c.lower(): c for c in choices}
    close += [folded[c] for c in difflib.get_close_matches(word.lower(), list(folded), n=n,
                                                           cutoff=CUTOFF)]
    return list(dict.fromkeys(same_case + close))[:n]


def did_you_mean(word, choices, *, quote: bool = True) -> str:
    """``"did you mean 'export'?"``: the one closest valid name, or ``""`` when none is alike.

    Examples
    --------
    >>> did_you_mean("super_stabel", ["super_stable", "super_stable_chain", "fourbar"])
    "did you mean 'super_stable'?"
    >>> did_you_mean("network", ["NETWORK"], quote=False)
    'did you mean NETWORK?'
    """
    names = close_names(word, choices, n=1)
    if not names:
        return ""
    return f"did you mean {names[0]!r}?" if quote else f"did you mean {names[0]}?"


def nearest_file(path, pattern: str = "*") -> str:
    """``"did you mean 'out/fourbar/laser_sheet1.dxf'?"``: the file beside a missing ``path``
    (among those matching ``pattern`` in its folder) whose name is closest to its name; ``""``
    when none is alike or the folder cannot be read.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as d:
    ...     (pathlib.Path(d) / "chain.toml").write_text("")
    ...     nearest_file(pathlib.Path(d) / "chian.toml") == f"did you mean '{d}/chain.toml'?"
    0
    True
    """
    from pathlib import Path

    path = Path(path)
    try:
        beside = sorted(p.name for p in path.parent.glob(pattern) if p.is_file()) \
            if path.parent.is_dir() else []
    except OSError:
        return ""
    found = close_names(path.name, beside, n=1)
    return f"did you mean '{path.parent / found[0]}'?" if found else ""
