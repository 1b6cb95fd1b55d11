"""The ``fabkit`` command line.

Subcommands live one per file in :mod:`fabkit.commands`; each module defines ``NAME``, ``HELP``,
``add_arguments(parser)`` and ``run(args) -> int``. They are discovered at start-up, so a new
command needs no edit here: their names and help are read from their source, and only the
module of the command run is imported (``fabkit --help`` imports none, ``fabkit templates`` only
its own), so that the command line starts at once. :func:`main` returns an exit code; fabkit
errors print as one line (``fabkit: error: ...``), tracebacks only with ``--debug``.

Exit codes: 0 ok; 1 a design or input failed (bad template, impossible motion, failed check);
2 usage error (bad option value, bad output folder choice); 70 internal error (a bug: one line
that says where, and how to report it); 128 + N after signal N, for every terminating signal
(129 SIGHUP, 130 Ctrl-C, 131 SIGQUIT, 138/140 SIGUSR1/2, 143 SIGTERM; 141 when the reader of the
output closed the pipe, quietly).
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import signal
import sys
from dataclasses import dataclass
from enum import IntEnum

from . import commands
from .commands import check_output_folder, examples_epilog
from .errors import FabkitError, internal_error_line, Interrupted
from .executor import install_signals, restore_signals
from .io.outputs import OutputFolder
from .io.suggest import did_you_mean

__all__ = ["main", "entry", "ExitCode"]


class ExitCode(IntEnum):
    OK = 0
    FAILED = 1      #: a design failed (bad input, impossible design, failed check)
    USAGE = 2       #: bad command line
    INTERNAL = 70   #: a bug in fabkit (EX_SOFTWARE of sysexits.h)
    INTERRUPTED = 130


@dataclass(frozen=True)
class _Command:
    """A subcommand as its module's source states it, before the module is imported."""

    module: str
    name: str
    help: str
    description: str


def _command_index() -> list:
    """Every subcommand (a module of :mod:`fabkit.commands` with ``NAME`` and ``run``), read
    from the modules' source: ``NAME``, ``HELP`` and ``DESCRIPTION`` when they are written as
    strings, else from the module, imported."""
    found = []
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        if info.name.startswith("_"):
            continue
        module = f"{commands.__name__}.{info.name}"
        stated = _stated(module)
        if stated is None or not isinstance(stated.get("HELP", ""), str) \
                or not isinstance(stated.get("DESCRIPTION", ""), str):
            mod = importlib.import_module(module)  # no source, or its help is computed
            stated = {key: getattr(mod, key) for key in ("NAME", "HELP", "DESCRIPTION", "run")
                      if hasattr(mod, key)}
        if isinstance(stated.get("NAME"), str) and "run" in stated:
            found.append(_Command(module, stated["NAME"], stated.get("HELP", ""),
                                  stated.get("DESCRIPTION", stated.get("HELP", ""))))
    return found


def _stated(module: str) -> dict | None:
    """The top-level string constants of a module's source, and ``run`` when it defines that
    function; None when there is no source to read. A constant that is not a string literal
    is given as None."""
    import ast
    import importlib.util
    from pathlib import Path

    try:
        origin = importlib.util.find_spec(module).origin
        tree = ast.parse(Path(origin).read_text(encoding="utf-8"))
    except (ImportError, AttributeError, TypeError, ValueError, OSError, SyntaxError):
        return None
    stated: dict = {}
    for node in tree.body:
        if isinstance(node, ast.FunctionDef) and node.name == "run":
            stated["run"] = True
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            for target in targets:
                if isinstance(target, ast.Name) and target.id in ("NAME", "HELP", "DESCRIPTION"):
                    value = node.value
                    stated[target.id] = value.value if isinstance(value, ast.Constant) \
                        and isinstance(value.value, str) else None
    return stated


def _commands():
    """The modules of every subcommand, imported."""
    return [importlib.import_module(c.module) for c in _command_index()]


class _Parser(argparse.ArgumentParser):
    """argparse with one-line usage errors (``fabkit: error: ...``, exit status 2), like every
    other error of the command line, that say "did you mean" for a misspelt command, choice
    or option."""

    def __init__(self, *args, **kwargs):
        # no abbreviated options: `--orbit 10` is not silently `--orbits 10`, and a new option
        # never changes what an old abbreviation meant
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)

    def error(self, message):
        command = self.prog.split(" ", 1)[1] if " " in self.prog else ""
        hint = f"fabkit {command} --help" if command else "fabkit --help"
        self.exit(ExitCode.USAGE, f"fabkit: error: {' '.join(message.split())} (see {hint})\n")

    def _check_value(self, action, value):
        # argparse's own check, with the nearest valid choice named (a command, --rank-method)

        if action.choices is not None and value not in action.choices:
            hint = did_you_mean(value, [str(c) for c in action.choices])
            choices = ", ".join(repr(c) for c in action.choices)
            raise argparse.ArgumentError(action, f"invalid choice: {value!r}"
                                                 + (f"; {hint}" if hint else "")
                                                 + f" (choose from {choices})")

    def parse_args(self, args=None, namespace=None):
        args, extra = self.parse_known_args(args, namespace)
        if extra:
            # said by the command's own parser, with the nearest option it has
            parser = _command_parser(self, getattr(args, "command", None)) or self
            parser.error(f"unrecognized arguments: {' '.join(extra)}"
                         + parser.option_hint(extra))
        return args

    def option_hint(self, extra) -> str:
        """``"; did you mean '--jobs'?"`` for the first unknown option in ``extra``."""
        known = [o for a in self._actions if a.help is not argparse.SUPPRESS
                 for o in a.option_strings]
        for word in extra:
            if word.startswith("-") and len(word) > 1:
                hint = did_you_mean(word.split("=", 1)[0], known)
                if hint:
                    return f"; {hint}"
        return ""


def _command_parser(parser, name):
    """The parser of subcommand ``name`` (None when there is none)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and name in action.choices:
            return action.choices[name]
    return None


class _Formatter(argparse.HelpFormatter):
    """argparse's help, with the ``Examples:`` section kept as written (one command a line)."""

    def _fill_text(self, text, width, indent):
        if text.startswith("Examples:"):
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)


#: The examples of ``fabkit --help``.
EXAMPLES_TEXT = """Examples:
  fabkit templates
      the bundled designs, one line each
  fabkit export super_stable --to dxf
      a laser-cut kit of a bundled design into out/super_stable/
  fabkit COMMAND --help
      a command's options and its own examples

Progress of long commands goes to stderr, shown when it is a terminal (--progress: always,
-q: never); results go to stdout. Exit codes: 0 ok, 1 a design or check failed, 2 usage error."""


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The parser of the command line.

    Parameters
    ----------
    only : str, optional
        Build the arguments of this command alone (``""``: of none); every other command is its
        name and help, and its module is not imported. Default: every command's arguments.
    """
    parser = _Parser(
        prog="fabkit",
        description="Design mechanical networks as iterated maps, simulate their motion, and "
                    "export them for laser cutting, origami and 3D printing.",
        epilog=EXAMPLES_TEXT, formatter_class=_Formatter,
    )
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    parser.add_argument("--version", action="version",
                        version=f"fabkit {__import__('fabkit').__version__}")
    parser.add_argument("--allow-large", action="store_true",
                        help="lift the size bounds (modules, samples, periods) checked before work")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    for command in _command_index():
        p = sub.add_parser(command.name, help=command.help, description=command.description,
                           formatter_class=_Formatter)
        if only is None or command.name == only:
            mod = importlib.import_module(command.module)
            p.epilog = examples_epilog(mod.EXAMPLES)
            mod.add_arguments(p)
            p.set_defaults(_run=mod.run)
    return parser


def _command_word(argv) -> str:
    """The command named on a command line (``""`` when none is): its first word that is not
    an option, since no option before the command takes a value."""
    for word in sys.argv[1:] if argv is None else argv:
        if word == "--":
            break
        if not word.startswith("-"):
            return word
    return ""


def main(argv=None) -> int:
    """Run the command line; returns the exit code."""
    if sys.stdout is None:  # started with stdout closed (>&-): Python gives no stream at all
        if sys.stderr is not None:
            print("fabkit: error: standard output is closed; give it a file or /dev/null "
                  "(> /dev/null)", file=sys.stderr)
        return ExitCode.FAILED
    parser = build_parser(only=_command_word(argv))
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse exits 2 on usage errors, 0 on --help
        return int(exc.code or 0)
    if not getattr(args, "_run", None):
        parser.print_help()
        return ExitCode.USAGE
    import os

    saved_large = os.environ.get("FABKIT_ALLOW_LARGE")
    if args.allow_large:  # an environment variable, so that worker processes see it too
        os.environ["FABKIT_ALLOW_LARGE"] = "1"
    previous = install_signals()
    import warnings

    quiet = warnings.catch_warnings()
    quiet.__enter__()
    if not args.debug:
        # the command line speaks in one-line messages; library warnings (numpy's invalid
        # values inside a check, matplotlib's layout notes) are for --debug
        warnings.simplefilter("ignore")
    try:
        _check_output_option(args)
        sys.stdout = _NamedStream(sys.stdout, "standard output")
        code = int(args._run(args))
        sys.stdout.flush()  # a closed pipe or a full disk shows here, not at exit
        return code
    except BrokenPipeError:
        # the reader went away (fabkit templates | head -1): end quietly, as after SIGPIPE
        _silence_stdout()
        return 128 + signal.SIGPIPE
    except FabkitError as exc:
        if args.debug:
            raise
        print(f"fabkit: error: {exc}", file=sys.stderr)
        return int(exc.exit_code)
    except Interrupted as exc:
        hint = f"; {exc.hint}" if exc.hint else ""  # what a command adds: where to resume
        print(f"fabkit: interrupted ({signal.Signals(exc.signum).name}){hint}", file=sys.stderr)
        return 128 + exc.signum
    except KeyboardInterrupt:
        print("fabkit: interrupted", file=sys.stderr)
        return ExitCode.INTERRUPTED
    except OSError as exc:  # a file-system condition met while working (disk full, permissions)
        if args.debug:
            raise
        if exc.filename == "standard output":  # its last flush on the way out fails too
            _silence_stdout()
        folder = getattr(args, "out_dir", None)
        # an error of a library writing through its own file object carries no name: the
        # output folder it was writing under is the one to look at
        named = getattr(exc, "filename", None)
        where = f"{named}: " if named else ""
        also = f" (output folder {folder})" if folder and not named else ""
        print(f"fabkit: error: {where}{exc.strerror or exc}{also}", file=sys.stderr)
        return ExitCode.FAILED
    except Exception as exc:  # a bug: one line that says where, the traceback with --debug
        if args.debug:
            raise
        print(f"fabkit: {internal_error_line(exc)}", file=sys.stderr)
        return ExitCode.INTERNAL
    finally:
        if isinstance(sys.stdout, _NamedStream):
            sys.stdout = sys.stdout.stream
        quiet.__exit__(None, None, None)
        restore_signals(previous)
        if saved_large is None:
            os.environ.pop("FABKIT_ALLOW_LARGE", None)
        else:
            os.environ["FABKIT_ALLOW_LARGE"] = saved_large


#: Argument names that hold a command's output folder (``-o/--out-dir``); checked before any
#: work.
OUTPUT_DESTS = ("out_dir",)


def _check_output_option(args) -> None:
    if getattr(args, "no_files", False):
        return
    for dest in OUTPUT_DESTS:
        value = getattr(args, dest, None)
        if isinstance(value, str):
            check_output_folder(value)
            # held from here on (opened now when it exists): a folder swapped later is noticed
            args.out_folder = OutputFolder.open(value)


class _NamedStream:
    """A text stream whose write errors name it (``standard output: No space left on
    device``): the error of a full disk under stdout carries no file name of its own."""

    def __init__(self, stream, name: str):
        self.stream = stream
        self.name = name

    def _named(self, call, *args):
        try:
            return call(*args)
        except BrokenPipeError:  # the reader went away: ended quietly by main()
            raise
        except OSError as exc:
            raise OSError(exc.errno, exc.strerror, self.name) from None

    def write(self, text):
        return self._named(self.stream.write, text)

    def flush(self):
        return self._named(self.stream.flush)

    def __getattr__(self, attr):
        return getattr(self.stream, attr)


def _silence_stdout() -> None:
    """Point stdout at /dev/null, so that the interpreter's last flush of a closed pipe does
    not raise again on the way out."""
    import os

    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # stdout is not a real file (a test's capture)
        pass


def entry() -> None:
    """Console-script entry point."""
    code = main()
    if code >= 128:
        # ended by a signal: every clean-up ran on the way out of main (temporary files,
        # staging folders, worker and check processes); end now, not after the interpreter's
        # teardown of numpy, scipy, trimesh and shapely (half a second on a busy machine)
        import os

        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    entry()
