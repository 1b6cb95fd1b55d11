"""Subcommands of the ``fabkit`` command line, one per file (see :mod:`fabkit.cli`)."""

from __future__ import annotations

from pathlib import Path

from ..errors import FabkitError

__all__ = ["expand_templates"]


def expand_templates(paths) -> list[Path]:
    """Template files named by files, folders (their ``*.toml``) and glob patterns, in order."""
    import glob

    out: list[Path] = []
    for raw in paths:
        p = Path(raw)
        if p.is_dir():
            found = sorted(p.glob("*.toml"))
            if not found:
                raise FabkitError(f"{p}: folder holds no *.toml templates")
            out.extend(found)
        elif any(ch in str(raw) for ch in "*?["):
            found = sorted(Path(g) for g in glob.glob(str(raw)))
            if not found:
                raise FabkitError(f"{raw}: no file matches")
            out.extend(found)
        else:
            out.append(p)
    seen, unique = set(), []
    for p in out:
        key = p.resolve()
        if key not in seen:
            seen.add(key)
            unique.append(p)
    return unique
