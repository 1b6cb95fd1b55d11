"""Reports.

``text`` renders report.json and report.md, ``html`` report.html and index.html, both from the
typed results of an export (never from a report read back). The pictures they hold are drawn by
:mod:`fabkit.plots`.
"""
