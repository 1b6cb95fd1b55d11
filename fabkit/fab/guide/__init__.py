"""Assembly guide of a laser-cut kit: A4 pages a person follows alone at the bench, and the
kit's pictures.

:func:`guide_pages` makes the PDF (and page PNGs): an overview that heads with the design's
verdict in words a maker acts on (:mod:`.verdict`), how the pages join, the kit's size and
contents; how to build (screw direction, washer placement, the build order page by page); a page
per two modules (or part of a network, in the order the network is built,
:func:`.plan.build_order`) in which every screw is closed on exactly one page (bars of other
pages that it takes are drawn there with their page; other pages name it), the hardware per
page as the bill of materials names it; a motion test with its numbers and, for a design with
more than one input, a functional test (:mod:`.function`: each input alone, then all of them).
The package splits along the work: :mod:`.plan` decides what goes where (pure data),
:mod:`.draw` draws bars and places labels that never overlap, :mod:`.pages` draws the pages,
:mod:`.pictures` the kit's assembly and motion pictures.
"""

from __future__ import annotations

from dataclasses import dataclass

from .function import FunctionTest, function_test
from .pages import A4, render_pages
from .verdict import NOT_JUDGED, verdict_rows
from .plan import (MODULES_PER_PAGE, GuidePage, GuidePlan, MotionTest, Sheet, guide_plan,
                   page_groups)
from .pictures import assembly_picture, motion_picture

__all__ = ["Guide", "guide_pages", "guide_plan", "GuidePlan", "GuidePage", "Sheet", "MotionTest", "A4",
           "MODULES_PER_PAGE", "page_groups", "assembly_picture", "motion_picture",
           "FunctionTest", "function_test", "verdict_rows", "NOT_JUDGED"]


@dataclass(frozen=True, eq=False)
class Guide:
    """An assembly guide.

    Attributes
    ----------
    pdf : bytes
        Every page, A4 portrait.
    images : list of bytes
        PNG of every page (only the first unless asked for all).
    texts : list of list of str
        The text on each page.
    plan : GuidePlan
    stats : dict
        ``pages``, ``labels``, ``overlaps`` (0), ``shrunk``, ``dropped``, ``smallest_pt``.
    """

    pdf: bytes
    images: list
    texts: list
    plan: GuidePlan
    stats: dict


def guide_pages(plan, bom: dict, *, verdict: dict | None = None, dpi: int = 100,
                pngs: bool = False, check: bool = False) -> Guide:
    """The assembly guide of a laser plan.

    Parameters
    ----------
    plan : fabkit.fab.laser_plan.LaserPlan
    bom : dict
        Its bill of materials (:func:`fabkit.writers.dxf.bill_of_materials`): hardware per
        joint and the part names the guide uses.
    verdict : dict, optional
        The design's verdict (``level``, ``text``, ``findings``, as report.json's
        ``verdict``): the first page heads with it in words a maker acts on; None: the first
        page says the design is not judged.
    dpi : int
        Resolution of the page PNGs.
    pngs : bool
        Render every page as PNG (the first page always is).
    check : bool
        List the texts that do not fit on their page (``stats["clipped"]``).

    Returns
    -------
    Guide
    """
    gp = guide_plan(plan, bom, verdict)
    pdf, images, texts, stats = render_pages(gp, plan, dpi=dpi, pngs=pngs, check=check)
    return Guide(pdf, images, texts, gp, stats)
