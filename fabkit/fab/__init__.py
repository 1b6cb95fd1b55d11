"""Geometry stage: turns a designed network into parts a maker can cut, fold or print.

One file per idea: ``hardware`` (screw catalogue), ``bars`` (outlines, holes, kerf), ``layers``
(stacking so nothing collides over the motion), ``nest`` (parts on sheets), ``creases``
(origami crease patterns), ``hinges`` (printed triangle-hinge networks).
"""
