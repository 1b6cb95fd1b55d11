"""``fabkit templates [FOLDER]``: the bundled templates, one line each."""

from __future__ import annotations

from pathlib import Path

NAME = "templates"
HELP = "list the bundled templates (or those in a folder), one line each"


def bundled_folder() -> Path:
    """The ``templates`` folder beside the package (a source checkout or an editable install)."""
    return Path(__file__).resolve().parents[2] / "templates"


def template_line(path: Path, width: int = 28) -> str:
    """``name  [figure]  description`` for a template; the reason instead when it is invalid."""
    from ..errors import FabkitError
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


def add_arguments(p):
    p.add_argument("folder", nargs="?", default=None,
                   help="folder of templates (default: the bundled templates)")


def run(args) -> int:
    from ..errors import FabkitError

    folder = Path(args.folder) if args.folder else bundled_folder()
    if not folder.is_dir():
        raise FabkitError(f"{folder}: no such folder of templates")
    paths = sorted(folder.glob("*.toml"))
    if not paths:
        raise FabkitError(f"{folder}: folder holds no *.toml templates")
    width = max(len(p.stem) for p in paths)
    for p in paths:
        print(template_line(p, width))
    return 0
