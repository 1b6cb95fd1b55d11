"""Geometry stage: turns a designed network into parts a maker can cut, fold or print.

One file per idea: ``laser`` (laser-cutting settings), ``hardware`` (screw catalogue), ``bars``
(outlines, holes, kerf), ``layers`` (stacking so nothing collides over the motion), ``nest``
(parts on sheets), ``creases`` (origami crease patterns), ``printing`` (print settings) and
``hinges`` (printed triangle-hinge networks).
"""
