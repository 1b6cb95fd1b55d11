"""Sphinx configuration of fabkit's reference: ``make docs`` builds it into out/docs/ with
warnings as errors.

Nothing here lists pages or modules by hand: every ``docs/*.md`` page is a chapter (the
``:glob:`` table of contents of index.rst), and every public module of the package is a page of
the API reference, found by walking the package (``autosummary`` with ``:recursive:``). A new
page or module appears without an edit here.
"""

import os
import re
from pathlib import Path
import sys
import warnings

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, ROOT)

import fabkit  # noqa: E402

# numpydoc reads some class docstrings a second time, without the hook below that names their
# ``Options`` section (a method's options) ``Other Parameters``; the page shows the section
warnings.filterwarnings("ignore", message="Unknown section Options", category=UserWarning)

project = "fabkit"
author = "fabkit contributors"
copyright = "fabkit contributors"
release = version = fabkit.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
templates_path = ["_templates"]
exclude_patterns = ["_build", "_autosummary/*.rst.tmp", "img/README*"]

# --- the API reference: every public module, found by walking the package ------------------
autosummary_generate = True
autosummary_generate_overwrite = True
autosummary_imported_members = False
# Each object on the page of the module that defines it, once: a package's ``__all__`` names
# what it re-exports from its modules, which document those names themselves (documenting
# them again under the package would describe one object twice). Public names without a
# docstring are listed too, so that every public function is named.
autodoc_default_options = {"members": True, "undoc-members": True, "ignore-module-all": True,
                           "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the numpydoc Parameters say the types, in words
autodoc_mock_imports = []

# numpydoc renders the Parameters/Returns/Examples sections; the class pages list their
# members through autodoc, so numpydoc's own member tables (which need their own pages) are off
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set = set()

# --- the chapters (docs/*.md, read by MyST) ----------------------------------------------------
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 4

html_theme = "alabaster"
html_title = f"fabkit {release}"
html_static_path: list = []


# --- the names of the top-level package -------------------------------------------------------

def _public_modules() -> list:
    """Every public module of the package (no part of its name starts with ``_``), imported."""
    import importlib
    import pkgutil

    found = [fabkit]
    for info in pkgutil.walk_packages(fabkit.__path__, "fabkit."):
        if not any(part.startswith("_") for part in info.name.split(".")):
            found.append(importlib.import_module(info.name))
    return found


def _where_defined(name: str, obj):
    """``(role, target)``: the documented place of ``fabkit.<name>``, the module that defines it
    (for a value, the module whose source gives it a ``#:`` comment)."""
    import inspect

    from sphinx.pycode import ModuleAnalyzer

    if inspect.ismodule(obj):
        if not hasattr(obj, name):  # a module of its own (fabkit.<name> is its page)
            return "mod", obj.__name__
        obj = getattr(obj, name)  # a function named as its module, which is imported
    if inspect.isclass(obj):
        return "class", f"{obj.__module__}.{obj.__qualname__}"
    if inspect.isfunction(obj):
        return "func", f"{obj.__module__}.{obj.__qualname__}"
    for module in _public_modules():
        if getattr(module, name, None) is obj:
            try:
                if ("", name) in ModuleAnalyzer.for_module(module.__name__).find_attr_docs():
                    return "data", f"{module.__name__}.{name}"
            except Exception:  # no source to read: look further
                continue
    return None, None


def _names_of_fabkit() -> list:
    """reST for ``fabkit.__all__``: each name with a link to where it is documented, names
    imported from the modules and those imported on first use alike."""
    import inspect

    lines = []
    for name in fabkit.__all__:
        obj = getattr(fabkit, name)
        role, target = _where_defined(name, obj)
        lines.append(f":{role}:`fabkit.{name} <{target}>`" if role else f"``fabkit.{name}``")
        documented = getattr(obj, name, obj) if inspect.ismodule(obj) else obj
        summary = (inspect.getdoc(documented) or "").split("\n\n")[0].replace("\n", " ")
        if not (inspect.isclass(documented) or inspect.isfunction(documented)
                or inspect.ismodule(documented)):
            summary = f"a {type(documented).__name__}"
        lines += [f"   {_escape_bars(summary) or '(no description)'}", ""]
    return lines


def _check_every_name_is_documented(app, exception) -> None:
    """After an HTML build: every public function and class of every public module has its
    entry, and the top-level page names every name of ``fabkit.__all__`` with a link to it.
    Anything missing fails the build, as a warning does."""
    import inspect

    if exception is not None or app.builder.name != "html":
        return
    html = "".join(p.read_text(encoding="utf-8")
                   for p in Path(app.outdir).rglob("*.html"))
    ids = set(re.findall(r'id="((?:module-)?fabkit[\w.]*)"', html))
    missing = []
    for module in _public_modules():
        for name, obj in vars(module).items():
            if not name.startswith("_") and (inspect.isfunction(obj) or inspect.isclass(obj)) \
                    and obj.__module__ == module.__name__ and f"{module.__name__}.{name}" not in ids:
                missing.append(f"{module.__name__}.{name}")
    top = (Path(app.outdir) / "api" / "_autosummary" / "fabkit.html").read_text(encoding="utf-8")
    for name in fabkit.__all__:
        role, target = _where_defined(name, getattr(fabkit, name))
        if f"fabkit.{name}<" not in re.sub(r"<span[^>]*>|</span>", "", top) \
                or (role and ("module-" * (role == "mod") + target) not in ids):
            missing.append(f"fabkit.{name} (from fabkit.__all__)")
    if missing:
        from sphinx.errors import ExtensionError

        raise ExtensionError(f"{len(missing)} public names are not in the reference: "
                             + ", ".join(sorted(missing)[:20]))


#: ``|x0 - x1|`` in a docstring is an absolute value, ``[A | b]`` a matrix beside a column,
#: plain text as ``help()`` shows them, never a reST substitution (no docstring uses those, nor
#: tables or line blocks): bars are escaped outside inline literals and roles.
_LITERAL = re.compile(r"(``.*?``|:\w+:`[^`]*`|`[^`]*`_?)")


def _escape_bars(line: str) -> str:
    parts = _LITERAL.split(line)
    for i in range(0, len(parts), 2):  # the even parts lie outside literals and roles
        parts[i] = re.sub(r"(?<!\\)\|", r"\\|", parts[i])
    return "".join(parts)


def _plain_docstring(app, what, name, obj, options, lines):
    """Docstrings as written, read by Sphinx as meant: absolute-value bars are text; an
    ``Options`` section (a method's options, given as ``trace(..., samples=...)``) is shown as
    numpydoc's ``Other Parameters``."""
    for i, line in enumerate(lines):
        if line.strip() == "Options" and i + 1 < len(lines) \
                and set(lines[i + 1].strip()) == {"-"}:
            indent = line[:len(line) - len(line.lstrip())]
            lines[i], lines[i + 1] = f"{indent}Other Parameters", f"{indent}{'-' * 16}"
        elif "|" in line:
            lines[i] = _escape_bars(line)


def setup(app):
    app.connect("autodoc-process-docstring", _plain_docstring, priority=400)  # before numpydoc
    app.connect("build-finished", _check_every_name_is_documented)
    from docutils.parsers.rst import Directive
    from docutils.statemachine import StringList
    from docutils import nodes

    class FabkitNames(Directive):
        """``.. fabkit-names::``: the definition list of ``fabkit.__all__``."""

        def run(self):
            node = nodes.container()
            self.state.nested_parse(StringList(_names_of_fabkit(), "fabkit.__all__"),
                                    self.content_offset, node)
            return node.children

    app.add_directive("fabkit-names", FabkitNames)
