"""The ``fabkit`` command line.

Subcommands live one per file in :mod:`fabkit.commands`; each module defines ``NAME``, ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``. They are discovered at start-up, so a new
command needs no edit here. :func:`main` returns an exit code; fabkit errors print as one line
(``fabkit: error: ...``), tracebacks only with ``--debug``.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from enum import IntEnum

from .errors import FabkitError

__all__ = ["main", "entry", "ExitCode"]


class ExitCode(IntEnum):
    OK = 0
    FAILED = 1      #: a design failed (bad input, impossible design, failed check)
    USAGE = 2       #: bad command line
    INTERRUPTED = 130


def _commands():
    from . import commands

    found = []
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        mod = importlib.import_module(f"{commands.__name__}.{info.name}")
        if hasattr(mod, "NAME") and hasattr(mod, "run"):
            found.append(mod)
    return found


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="fabkit",
        description="Design mechanical networks as iterated maps, simulate their motion, and "
                    "export them for laser cutting, origami and 3D printing.",
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--version", action="version",
                        version=f"fabkit {__import__('fabkit').__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for mod in _commands():
        p = sub.add_parser(mod.NAME, help=mod.HELP, description=getattr(mod, "DESCRIPTION", mod.HELP))
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def main(argv=None) -> int:
    """Run the command line; returns the exit code."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse exits 2 on usage errors, 0 on --help
        return int(exc.code or 0)
    if not getattr(args, "_run", None):
        parser.print_help()
        return ExitCode.USAGE
    try:
        return int(args._run(args))
    except FabkitError as exc:
        if args.debug:
            raise
        print(f"fabkit: error: {exc}", file=sys.stderr)
        return ExitCode.FAILED
    except KeyboardInterrupt:
        print("fabkit: interrupted", file=sys.stderr)
        return ExitCode.INTERRUPTED


def entry() -> None:
    """Console-script entry point."""
    sys.exit(main())


if __name__ == "__main__":  # pragma: no cover
    entry()
