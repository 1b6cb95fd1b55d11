"""Crease patterns: a flat sheet with mountain/valley creases <-> the 3D bar-and-joint network.

The paper models creased paper as a linkage: every crease and boundary segment is a rigid edge,
every crease intersection or corner a node. A :class:`CreasePattern` holds the flat pattern
(vertices in the plane, edges with an assignment, faces); :func:`network_from_pattern` turns it
into the :class:`~fabkit.model.network.Network` the simulator folds; :func:`fold_angles` reads the
signed fold angle of every crease off folded node positions.

Rigid panels: a triangular panel is rigid by its three edges. A panel with n >= 4 vertices (a
face, or faces joined across facet diagonals "F") is triangulated in the plane (2n - 3 bars fix
its shape in the plane), and one **apex node** is added off the panel, above its centroid at a
height of half the square root of its area, joined by a bar to each of the n panel vertices.
Bars between coplanar points cannot stop the panel bending out of its plane to first order (a
flat quad with both diagonals is rigid but keeps a spurious infinitesimal flex), while the apex
bars can: panel plus apex is a triangulated pyramid, rigid and infinitesimally rigid. The count
is exact: the panel alone has 3n - (2n - 3) - 6 = n - 3 bending motions; the apex adds 3
coordinates and n bars, removing n - 3. So the network has exactly the motions of the rigid
origami, no spurious ones. Apex nodes are internal: they are not written to SVG or FOLD files.

Signed fold angles follow FOLD: in degrees, positive for a valley, negative for a mountain,
seen from the side the flat pattern's counter-clockwise faces face (+z).

The package splits along the work: :mod:`.pattern` (the flat pattern and its network, fold
angles, flat foldability), :mod:`.folding` (origami designs from templates and their folding
through the flat state) and :mod:`.chains` (chains of sheets).
"""

from .chains import CHAIN_JOIN, sheet_chain
from .folding import FoldResult, OrigamiModel, Sheet, fold_model, folded_assignment, origami_model
from .pattern import (
                      ASSIGNMENTS,
                      CreasePattern,
                      assignment_score,
                      flat_foldability,
                      fold_angles,
                      network_from_pattern,
                      planar_faces,
)

__all__ = [
    "ASSIGNMENTS",
    "CreasePattern",
    "planar_faces",
    "network_from_pattern",
    "fold_angles",
    "assignment_score",
    "flat_foldability",
    "Sheet",
    "OrigamiModel",
    "origami_model",
    "FoldResult",
    "fold_model",
    "folded_assignment",
    "sheet_chain",
    "CHAIN_JOIN",
]
