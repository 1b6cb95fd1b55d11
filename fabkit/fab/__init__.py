"""Geometry stage: turns a designed network into parts a maker can cut, fold or print.

One file per idea: ``laser`` (the laser kit's motion window and kerf note), ``hardware`` (the
parts to order), ``bars`` (outlines, holes, kerf), ``layers`` (stacking so nothing collides over
the motion), ``nest`` (parts on sheets), ``creases`` (origami crease patterns), ``hinges``
(printed triangle-hinge networks), ``pinned`` (bars printed in place on pins), ``printers`` (bed
layout) and ``slicer`` (what the 3MF tells the slicer). What a design asks of each process, and
the catalogues (screws, printers, filaments), are :mod:`fabkit.settings`.
"""
