"""Pictures as matplotlib figures, below every stage that draws.

``viz`` draws networks and motions, ``animate`` makes GIFs of a motion, ``mapplots`` the map and
its cobweb, ``designplots`` designed modules and chains. Library code builds ``Figure`` objects
and never switches matplotlib's backend; saving is the caller's job. The reports
(:mod:`fabkit.report`) and the guide's pages draw with these.
"""
