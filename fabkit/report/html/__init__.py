"""Self-contained HTML reports: ``report.html`` per design and ``index.html`` for a batch.

A design's page is rendered from the typed results of its export
(:class:`fabkit.pipeline.stages.DesignReport`: the verdict, the traced motion, each format's result
and checks, the tolerance analysis, the files in memory), never from a report read back; its
traced motion becomes a scrubbable drawing: drag the slider (or
press play) and watch the network move, its bars coloured by laser layer, by crease assignment
(mountain red, valley blue, boundary black) or grey for a print, with the ports drawn dashed. The
page also shows the map and cobweb, the laser layers over the motion, the crease pattern, the
printed part and its bed layout, the bill of materials, the tolerance analysis and every check's
verdict. Pictures are inlined (data URIs, inline SVG): the page needs no network and no other file.

``index.html`` lists every design of a batch with its own moving picture, its verdict and a link to
its page, from the :class:`fabkit.pipeline.stages.IndexCard` each export hands back (designs
exported into the folder by earlier runs are linked by name).

One module per part of the page: :mod:`~fabkit.report.html.frame` (style and player),
:mod:`~fabkit.report.html.checks` (the verdict and every check),
:mod:`~fabkit.report.html.lead` (what the design is made for),
:mod:`~fabkit.report.html.folder` (the files and exports of the folder),
:mod:`~fabkit.report.html.motion` (the motion drawing and the map),
:mod:`~fabkit.report.html.laser`, :mod:`~fabkit.report.html.origami` and
:mod:`~fabkit.report.html.printed` (each process's pictures and bill of materials),
:mod:`~fabkit.report.html.tolerance`, with :mod:`~fabkit.report.html.design` putting a design's
page together and :mod:`~fabkit.report.html.index` the batch's; what they share is in
:mod:`~fabkit.report.html.common`.
"""

from __future__ import annotations

from .common import image_size, LEVEL_CLASS, PROCESSES
from .design import design_html
from .folder import describe_file, FILE_ROLES, not_exported
from .index import index_card, index_html, IndexCard, write_index
from .motion import motion_frames
from .tolerance import keep_chart_svg

__all__ = ["design_html", "index_html", "index_card", "write_index", "motion_frames",
           "keep_chart_svg", "describe_file", "not_exported", "image_size", "PROCESSES",
           "FILE_ROLES", "LEVEL_CLASS", "IndexCard"]
