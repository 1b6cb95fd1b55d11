"""fabkit: mechanical networks as iterated maps, from design to fabrication.

The core (model, kinematics, maps, design, io) never imports the fabrication, export or
command-line layers.
"""

from .errors import (
    BoundsError,
    ConstructionError,
    DesignError,
    FabkitError,
    FabricationError,
    KinematicsError,
    NetworkError,
    SettingsError,
    TemplateError,
)
from .model.network import Network
from .model.rigidity import ModeCount, count_modes, rigid_body_basis, rigidity_matrix
from .kinematics import METHODS, Trajectory, trace
from .templates import Design, load_template

__version__ = "0.1.0"

# Names provided by modules that are imported on first use (keeps `import fabkit` light).
_LAZY = {
    "chain": "fabkit.design.assemble",
    "join_transform": "fabkit.design.assemble",
    "join": "fabkit.design.assemble",
    "branch": "fabkit.design.assemble",
    "tessellate": "fabkit.design.assemble",
    "design_curve": "fabkit.design.letters",
    "design_word": "fabkit.design.letters",
    "glyph": "fabkit.design.letters",
    "motion_gif": "fabkit.plots.animate",
    "module_map": "fabkit.maps",
    "Map1D": "fabkit.maps",
    "design_module": "fabkit.design.solution_space",
    "design_map": "fabkit.design",
    "design_curve_chain": "fabkit.design",
    "read_curve": "fabkit.design",
    "SolutionSpace": "fabkit.design.solution_space",
    "fold_through": "fabkit.kinematics.branching",
    "analyze_bifurcation": "fabkit.kinematics.branching",
    "sweep": "fabkit.sweep",
    "export": "fabkit.pipeline.api",
    "laser_builds": "fabkit.tolerance.builds",
}

# Modules of the package imported on first use (``fabkit.plot.cobweb(...)`` after
# ``import fabkit``).
_SUBMODULES = ("plot",)


def __getattr__(name):
    import importlib

    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    if name in _SUBMODULES:
        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module 'fabkit' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY) | set(_SUBMODULES))


__all__ = [
    "BoundsError",
    "ConstructionError",
    "Design",
    "DesignError",
    "FabkitError",
    "FabricationError",
    "KinematicsError",
    "METHODS",
    "ModeCount",
    "Network",
    "NetworkError",
    "SettingsError",
    "TemplateError",
    "Trajectory",
    "count_modes",
    "load_template",
    "rigid_body_basis",
    "rigidity_matrix",
    "trace",
    *sorted(_LAZY),
    *_SUBMODULES,
]
