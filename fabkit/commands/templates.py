"""``fabkit templates [FOLDER]``: the bundled templates, one line each, and where they live.

The bundled templates are listed from their files' top-level keys (name, figure, description),
none of them built, so that the listing is instant; those of a FOLDER are loaded, each line with
the template's size, or the reason it does not load.

``fabkit templates --copy NAME [DIR]`` copies a bundled template, with the templates it refers to
(a chain's module), into DIR to be edited; the references still resolve in the copy.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from ..errors import FabkitError, OutputError, UsageError
from ..io.outputs import OutputFolder
from ..io.suggest import did_you_mean
from ..templates import bundled_folder, bundled_names, is_template_name, resolve_template
from . import add_out_dir, check_output_folder, Example

NAME = "templates"
HELP = ("list the bundled templates (or those in a folder), one line each; --copy NAME [DIR] "
        "copies one to edit")

EXAMPLES = [
    Example("fabkit templates", "the bundled designs, one line each, and their folder"),
    Example("fabkit templates --copy super_stable_chain -o mine",
            "the chain and its module into mine/, to edit; then fabkit info "
            "mine/super_stable_chain.toml"),
    Example("fabkit templates mine", "the templates of a folder of your own",
            needs=("fabkit templates --copy super_stable_chain -o mine",)),
]


def template_line(path: Path, width: int = 28) -> str:
    """``name  [figure]  description`` for a template; the reason instead when it is invalid."""
    from ..templates import load_template

    try:
        design = load_template(path)
    except FabkitError as exc:
        return f"{path.stem:<{width}}  (invalid: {exc})"
    fig = design.raw.get("figure", "")
    fig = f"[{fig}] " if isinstance(fig, str) and fig else ""
    net = design.network
    size = f"{net.dim}D {net.n_nodes}n/{net.n_edges}e"
    return f"{design.name:<{width}}  {size:<13} {fig}{design.description}".rstrip()


def header_line(path: Path, width: int = 28) -> str:
    """``name  [figure]  description`` of a template, read from its file's top-level keys alone:
    nothing is built (the bundled listing; ``fabkit info NAME`` gives the sizes). A file that
    cannot be read as TOML is listed with the reason."""
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib

    try:
        raw = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        return f"{path.stem:<{width}}  (invalid: {' '.join(str(exc).split())})"
    name, fig, text = (raw.get(key) for key in ("name", "figure", "description"))
    name = name if isinstance(name, str) and name else path.stem
    fig = f"[{fig}] " if isinstance(fig, str) and fig else ""
    text = text if isinstance(text, str) else ""
    return f"{name:<{width}}  {fig}{text}".rstrip()


def add_arguments(p):
    p.add_argument("folder", nargs="?", default=None, metavar="FOLDER",
                   help="folder of templates to list (default: the bundled templates); with "
                        "--copy, the folder to copy into (default: the current folder)")
    p.add_argument("--copy", metavar="NAME", default=None,
                   help="copy the bundled template NAME and the templates it refers to into "
                        "FOLDER, to edit")

    add_out_dir(p, None, "with --copy: the folder to copy into (as FOLDER; default: the "
                         "current folder)")
    p.add_argument("--force", action="store_true",
                   help="with --copy: overwrite files that already exist")


def template_files(name: str) -> dict[str, Path]:
    """The files of a bundled template and of every template it refers to, by their path
    relative to the bundled folder (``{"fourbar_chain2.toml": ..., "fourbar.toml": ...}``).

    Raises
    ------
    UsageError
        ``name`` is not the name of a bundled template.
    FabkitError
        A referenced template lies outside the bundled folder (it could not be copied with the
        same relative path).
    """
    from ..templates import bundled_folder, bundled_template, load_template

    try:
        path = bundled_template(name)
    except KeyError:
        hint = did_you_mean(name.removesuffix(".toml"), bundled_names()) \
            if is_template_name(name) else ""
        raise UsageError("--copy", f"no bundled template {name!r}; " + (f"{hint} " if hint else "")
                         + "`fabkit templates` lists them") from None
    root = bundled_folder().resolve()
    files: dict[str, Path] = {}
    todo = [load_template(path)]
    while todo:
        design = todo.pop()
        source = design.path.resolve()
        try:
            rel = source.relative_to(root).as_posix()
        except ValueError:
            raise FabkitError(f"{name}: refers to {source}, outside the bundled templates "
                              f"({root}); it cannot be copied beside them") from None
        if rel not in files:
            files[rel] = source
            todo.extend(design.references.values())
    return files


def copy_template(name: str, folder, force: bool = False) -> list[Path]:
    """Copy a bundled template and the templates it refers to into ``folder``, keeping their
    relative paths so that the references still resolve; returns the files written (the
    template first).

    Nothing is written when any of the files exists (unless ``force``), and nothing is written
    outside ``folder``.

    Raises
    ------
    UsageError
        Not a bundled template's name.
    OutputError
        A file exists (without ``force``), or is not a regular file.
    """
    held = OutputFolder.open(folder, "FOLDER")  # one handle: looked at and written through it
    files = template_files(name)
    for rel in files:
        st = _entry(held, Path(rel).as_posix())
        target = held.path / rel
        if st is None:
            continue
        if not stat.S_ISREG(st.st_mode) and not stat.S_ISLNK(st.st_mode):
            raise OutputError(target, "exists and is not a file; choose another folder")
        if not force:
            raise OutputError(target, "exists; give --force to overwrite it, or choose "
                                      "another folder")
    data = {Path(rel).as_posix(): source.read_bytes() for rel, source in files.items()}
    written = held.write_files(data)  # all or nothing, never through a link, never outside
    folder = held.path
    first = folder / Path(next(iter(files))).as_posix()
    return sorted(written, key=lambda p: p != first)


def _entry(held: OutputFolder, rel: str):
    """The status of entry ``rel`` (a relative POSIX path) below the folder held, a link's own
    (never followed), or None when it or a folder above it is missing."""
    *above, name = rel.split("/")
    if held.identity is None and not os.path.lexists(held.path):
        return None  # the folder is created when written: nothing is in the way
    where = held
    for part in above:
        if not where.is_folder(part):
            return where.lstat(part)  # a file or a link where a folder goes: in the way
        where = where.folder(part, create=False)
    return where.lstat(name)


def _copy(args) -> int:
    folder = getattr(args, "out_folder", None)  # -o: held by the command line already
    if folder is None:
        folder = Path(args.folder) if args.folder else Path()
        check_output_folder(folder, "FOLDER")
    written = copy_template(args.copy, folder, force=args.force)
    for path in written:
        print(f"wrote {path}")
    print(f"edit it, then e.g.: fabkit info {written[0]}")
    return 0


def _list_bundled() -> int:
    folder = bundled_folder()
    paths = sorted(folder.glob("*.toml"))
    if not paths:
        raise FabkitError(f"{folder}: no bundled templates; the installed package is "
                          "incomplete, reinstall fabkit")
    width = max(len(p.stem) for p in paths)
    print(f"{len(paths)} bundled templates in {folder}:")
    for p in paths:  # the bundled templates load (tests/test_bundled.py): read, not built
        line = header_line(p, width)
        own = resolve_template(p.stem)
        if own.resolve() != p.resolve():  # a user's own file of this name wins
            line += f"  [{own} in this folder is used instead]"
        print(line)
    print("Give a name where a template file goes (fabkit export super_stable --to dxf); "
          "fabkit templates --copy NAME [FOLDER] copies one to edit.")
    return 0


def run(args) -> int:
    if args.out_dir is not None:
        if args.copy is None:
            raise UsageError("-o", "is the folder --copy copies into; give it with --copy NAME")
        if args.folder is not None:
            raise UsageError("-o", f"and FOLDER ({args.folder}) both name the folder to copy "
                                   "into; give one")
        args.folder = args.out_dir
    if args.copy is not None:
        return _copy(args)
    if args.force:
        raise UsageError("--force", "only goes with --copy NAME")
    if args.folder is None:
        return _list_bundled()
    folder = Path(args.folder)
    if not folder.is_dir():
        raise FabkitError(f"{folder}: no such folder of templates")
    paths = sorted(folder.glob("*.toml"))
    if not paths:
        raise FabkitError(f"{folder}: folder holds no *.toml templates")
    width = max(len(p.stem) for p in paths)
    for p in paths:
        print(template_line(p, width))
    return 0
