"""The network model and what can be proved about it.

A :class:`~fabkit.model.network.Network` is nodes, bars and named ports (``network``);
``construction`` finds the order in which its nodes are placed two bars at a time; ``matrix`` builds
the rigidity matrix and holds the linear algebra the others share; ``rigidity`` counts modes, proved
from a construction order where one exists (``certificate``) and numerically otherwise;
``independent_edges`` picks the independent bars of a self-stressed network. Everything else in
fabkit stands on these modules; they import nothing of fabkit but the errors, the argument checks
and the shared numerics.
"""
