"""Reports and pictures.

``text`` renders report.json and report.md, ``html`` report.html and index.html, both from the
typed results of an export (never from a report read back). ``viz`` draws networks and motions as
matplotlib figures, ``animate`` makes GIFs of a motion, ``mapplots`` the map and its cobweb,
``designplots`` designed modules and chains. Library code builds ``Figure`` objects and never
switches matplotlib's backend; saving is the caller's job.
"""
