"""What a design asks of each process, and the catalogues it chooses from.

The writers (:mod:`fabkit.fab`, :mod:`fabkit.writers`) plan and draw from these; the as-built
checks (:mod:`fabkit.check`) hold the written files to them. Neither side's code is in here, so
a check that reads the settings shares nothing with the way a file was drawn.

One file per idea: ``laser`` (the ``[fabrication.laser]`` table: :class:`~.laser.LaserSettings`),
``printing`` (the ``[fabrication.print]`` table: :class:`~.printing.PrintSettings`),
``origami`` (the ``[fabrication.origami]`` table: :class:`~.origami.OrigamiSettings`),
``design`` (all of a design's settings resolved once, with the command line's overrides:
:class:`~.design.DesignSettings`, what every stage below the entry reads), ``printers``
(printer beds), ``filaments`` (what the slicer is told of each material) and ``fasteners`` (the
catalogue of screws, pins and washers, and the fastener each joint's stack takes).
"""
