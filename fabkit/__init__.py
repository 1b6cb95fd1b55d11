"""fabkit: mechanical networks as iterated maps, from design to fabrication.

The core (network, rigidity, kinematics, maps, design, assemble, templates) never imports the
fabrication, export or command-line layers.
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
from .network import Network
from .rigidity import ModeCount, count_modes, rigid_body_basis, rigidity_matrix
from .kinematics import METHODS, Trajectory, trace
from .templates import Design, load_template

__version__ = "0.1.0"

# Names provided by modules that are imported on first use (keeps `import fabkit` light).
_LAZY = {
    "chain": "fabkit.assemble",
    "join_transform": "fabkit.assemble",
    "join": "fabkit.assemble",
    "branch": "fabkit.assemble",
    "tessellate": "fabkit.assemble",
    "design_curve": "fabkit.letters",
    "design_word": "fabkit.letters",
    "glyph": "fabkit.letters",
    "motion_gif": "fabkit.animate",
    "module_map": "fabkit.maps",
    "Map1D": "fabkit.maps",
    "design_module": "fabkit.design",
    "design_map": "fabkit.designer",
    "design_curve_chain": "fabkit.designer",
    "read_curve": "fabkit.designer",
    "SolutionSpace": "fabkit.design",
    "fold_through": "fabkit.kinematics.branching",
    "analyze_bifurcation": "fabkit.kinematics.branching",
    "sweep": "fabkit.sweep",
}


def __getattr__(name):
    import importlib

    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'fabkit' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


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
]
