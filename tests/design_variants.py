"""Copies of a design that are physically the same: nodes renumbered, the whole design moved
rigidly, its coordinates perturbed far below any fabrication error.

A verdict, a mode count or a layer plan is a property of the design, so it must not change on
such a copy. Renumbering reorders every sum and factorisation over the nodes; a rigid move
changes every coordinate's last bits; a perturbation of 1e-12 (relative to the design's size)
moves a design that sits exactly at a threshold (a flat state, a fixed point at a fold) off it
by far less than any maker could tell.
"""

from __future__ import annotations

import copy
import dataclasses

import numpy as np

from fabkit.model.network import Assembly, Network

__all__ = ["renumbered", "moved", "perturbed", "VARIANTS"]

#: Keys of ``[fabrication.*]`` tables that hold lists of node indices.
_NODE_LISTS = {("origami", "sheets"), ("origami", "faces"), ("print", "rigid_triangles")}


def _with_network(design, net: Network, fabrication=None):
    return dataclasses.replace(design, network=net,
                               fabrication=design.fabrication if fabrication is None
                               else fabrication)


def renumbered(design, seed: int = 1):
    """The design with its nodes in a random order (edges keep their order and their ends)."""
    net = design.network
    n = net.n_nodes
    perm = np.random.default_rng(seed).permutation(n)  # old node i -> new node perm[i]
    nodes = np.empty_like(net.nodes)
    nodes[perm] = net.nodes
    labels = None
    if net.labels is not None:
        labels = [None] * n
        for i, s in enumerate(net.labels):
            labels[perm[i]] = s
    assembly = None
    if net.assembly is not None:
        assembly = Assembly.from_copies(tuple((m, perm[np.asarray(idx)], mir)
                                              for m, idx, mir in net.assembly.copies),
                                        net.assembly.d_in)
    ports = {k: (int(perm[i]), int(perm[j])) for k, (i, j) in net.ports.items()}
    fab = copy.deepcopy(design.fabrication)
    for table, key in _NODE_LISTS:
        section = fab.get(table) if isinstance(fab, dict) else None
        if isinstance(section, dict) and isinstance(section.get(key), list):
            section[key] = [[int(perm[v]) for v in row] for row in section[key]]
    new = Network(nodes, perm[net.edges], ports, labels, assembly)
    return _with_network(design, new, fab)


def _rotation(dim: int, rng) -> np.ndarray:
    if dim == 2:
        t = rng.uniform(0.0, 2.0 * np.pi)
        return np.array([[np.cos(t), -np.sin(t)], [np.sin(t), np.cos(t)]])
    q, r = np.linalg.qr(rng.standard_normal((3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def moved(design, seed: int = 2):
    """The design rotated (a proper rotation) and translated as a whole."""
    net = design.network
    rng = np.random.default_rng(seed)
    rot = _rotation(net.dim, rng)
    shift = rng.uniform(-3.0, 3.0, net.dim) * net.size
    new = Network(net.nodes @ rot.T + shift, net.edges, net.ports, net.labels, net.assembly)
    return _with_network(design, new)


def perturbed(design, seed: int = 3, rel: float = 1e-12):
    """The design with every coordinate moved by ``rel`` of its size (normal draws)."""
    net = design.network
    noise = np.random.default_rng(seed).standard_normal(net.nodes.shape)
    new = Network(net.nodes + rel * net.size * noise, net.edges, net.ports, net.labels,
                  net.assembly)
    return _with_network(design, new)


#: name -> function(design) -> the copy
VARIANTS = {"renumbered": renumbered, "moved": moved, "perturbed": perturbed}
