""""Did you mean": the nearest valid names to a misspelt one (commands, options, templates,
formats, methods, settings), for the one-line errors."""

from __future__ import annotations

import difflib

__all__ = ["close_names", "did_you_mean"]

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
