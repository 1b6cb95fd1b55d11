"""The slop of ports over the joints' play (fabkit.builds.slop), checked from first principles.

Every reference here is computed in the test with numpy alone: the closed form ``Σ|λ_e| c_e`` of
an isostatic network (``λ`` from a dense least-squares solve), the nonlinear 4-bar placed by
circle intersections at the corners of the play box, and a self-stressed network's slop by
enumerating the vertices of the compatible play and by its dual (the least ``Σ|λ_e| c_e`` over
the line of solutions ``λ``).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import fabkit
from fabkit.builds import slop as slop_module
from fabkit.builds.slop import PortSlop, port_slop
from fabkit.model.network import Network


# -- references written here -------------------------------------------------------------------

def _rows(x: np.ndarray, pairs) -> np.ndarray:
    """Dense unit rows of node pairs: (x_i - x_j)/|x_i - x_j| at i's columns, minus at j's."""
    x = np.asarray(x, dtype=float)
    n, d = x.shape
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    out = np.zeros((len(pairs), d * n))
    for k, (i, j) in enumerate(pairs):
        v = x[i] - x[j]
        v = v / np.linalg.norm(v)
        out[k, d * i:d * i + d] = v
        out[k, d * j:d * j + d] = -v
    return out


def _lambda(x, edges, held, port) -> np.ndarray:
    """``λ_e = ∂d_port/∂s_e`` of a network that is isostatic with the held pairs: solve
    ``[R; R_h] u = [e_k; 0]`` for every unit length change and read the port's row."""
    r = _rows(x, edges)
    a = np.vstack([r, _rows(x, held)])
    assert np.linalg.matrix_rank(a) == a.shape[0], "not isostatic: the rows are dependent"
    rhs = np.zeros((a.shape[0], r.shape[0]))
    rhs[:r.shape[0]] = np.eye(r.shape[0])
    u = np.linalg.lstsq(a, rhs, rcond=None)[0]
    assert np.allclose(a @ u, rhs, atol=1e-12)
    return _rows(x, [port])[0] @ u


def _fourbar():
    design = fabkit.load_template("fourbar")
    return design.network


def _traced(net, to):
    traj = fabkit.trace(net, drive="d1", to=to)
    assert traj.status == "finished"
    return traj.positions[-1]


# -- 1. closed form of an isostatic network -----------------------------------------------------

@pytest.mark.parametrize("state", ["start", "traced"])
def test_fourbar_matches_the_closed_form(state):
    net = _fourbar()
    assert net.edges.tolist() == [[0, 2], [0, 3], [1, 2], [1, 3]]
    x = net.nodes if state == "start" else _traced(net, 2.5)
    room = np.array([0.1, 0.25, 0.05, 0.3])
    lam = _lambda(x, net.edges, [net.port("d1")], net.port("d2"))
    expected = float(np.abs(lam) @ room)
    [got] = port_slop(net, x, room, held=[net.port("d1")])
    assert got.port == "d2" and got.bounded
    assert got.increase == pytest.approx(expected, rel=1e-9)
    assert got.decrease == pytest.approx(expected, rel=1e-9)
    assert got.largest == pytest.approx(expected, rel=1e-9)


def test_three_dimensional_network_matches_the_closed_form():
    # a tetrahedron missing bar 0-1 (held instead) with a node 4 on the triangle 1, 2, 3
    x = np.array([[0, 0, 0], [1.1, 0, 0], [0.4, 1.0, 0.1], [0.3, 0.4, 0.9], [1.2, 0.9, 0.8]])
    edges = [[0, 2], [0, 3], [1, 2], [1, 3], [2, 3], [1, 4], [2, 4], [3, 4]]
    net = Network(x, edges, ports={"a": (0, 4), "b": (2, 0)})
    room = np.linspace(0.01, 0.08, len(edges))
    got = port_slop(net, x, room, held=[(0, 1)])
    for s in got:
        lam = _lambda(x, edges, [(0, 1)], net.port(s.port))
        assert s.largest == pytest.approx(float(np.abs(lam) @ room), rel=1e-9)


# -- 2. the nonlinear 4-bar, by brute force ------------------------------------------------------

def _place(x0, x1, r0, r1, side):
    """Points at distances r0 from x0 and r1 from x1 (arrays of radii), on ``side`` of x0→x1."""
    base = x1 - x0
    dist = np.linalg.norm(base)
    along = (dist ** 2 + r0 ** 2 - r1 ** 2) / (2 * dist)
    height = np.sqrt(r0 ** 2 - along ** 2)
    unit = base / dist
    normal = np.array([-unit[1], unit[0]])
    return x0 + along[:, None] * unit + side * height[:, None] * normal


def _fourbar_d2(x, s):
    """d2 of the 4-bar with nodes 0 and 1 where they are (d1 held) and bar lengths L + s."""
    lengths = np.linalg.norm(x[[0, 0, 1, 1]] - x[[2, 3, 2, 3]], axis=1)  # bars 0-2 0-3 1-2 1-3
    ell = lengths + s
    base = x[1] - x[0]

    def side(k):
        v = x[k] - x[0]
        return np.sign(base[0] * v[1] - base[1] * v[0])

    p2 = _place(x[0], x[1], ell[:, 0], ell[:, 2], side(2))
    p3 = _place(x[0], x[1], ell[:, 1], ell[:, 3], side(3))
    return np.linalg.norm(p2 - p3, axis=1)


def _brute_force(x, c, seed=7):
    """Largest increase and decrease of d2 over the corners of the play box, over random
    interior points, and the corners' sign patterns at the two extremes."""
    nominal = _fourbar_d2(x, np.zeros((1, 4)))[0]
    assert nominal == pytest.approx(np.linalg.norm(x[2] - x[3]), abs=1e-9)
    signs = np.array(list(itertools.product([-1.0, 1.0], repeat=4)))
    corners = _fourbar_d2(x, signs * c)
    inside = _fourbar_d2(x, np.random.default_rng(seed).uniform(-c, c, size=(400, 4)))
    return (corners.max() - nominal, nominal - corners.min(),
            inside.max() - nominal, nominal - inside.min(),
            signs[corners.argmax()], signs[corners.argmin()])


@pytest.mark.parametrize("shape", ["template", "generic"])
def test_fourbar_brute_force_over_the_play_box(shape):
    net = _fourbar()
    x = 100.0 * _traced(net, 2.5)  # mm, a regular state
    if shape == "generic":
        # the template is an antiparallelogram (opposite bars equal): d1·d2 = b² - a², so at a
        # corner of the box ((b + c)² - (a - c)²)/d1 is linear in c, and the first-order slop is
        # exact there. Moving nodes 2 and 3 makes a 4-bar with four different bars.
        x[2] += [-10.0, 25.0]
        x[3] += [30.0, -20.0]
        net = net.with_nodes(x)
        assert np.ptp(net.edge_lengths) > 50.0
    held = [net.port("d1")]
    lam = _lambda(x, net.edges, held, net.port("d2"))
    assert (np.abs(lam) > 0.1).all()

    errors = []
    for c in (0.2, 0.1):
        up, down, up_in, down_in, arg_up, arg_down = _brute_force(x, np.full(4, c))
        assert up >= up_in and down >= down_in  # the extremes are at corners
        assert np.array_equal(arg_up, np.sign(lam)) and np.array_equal(arg_down, -np.sign(lam))
        [got] = port_slop(net, x, np.full(4, c), held=held)
        assert abs(got.increase - up) / got.increase < 0.02
        assert abs(got.decrease - down) / got.decrease < 0.02
        errors.append(max(abs(got.increase - up), abs(got.decrease - down)) / got.increase)
    if shape == "template":
        assert max(errors) < 1e-9
    else:
        # second order: the relative error is of the order of c over the bars' length, and
        # halves with the room
        assert 1e-5 < errors[0] < 1e-2
        assert errors[0] / errors[1] == pytest.approx(2.0, rel=0.05)


# -- 3. compatibility: a network with a state of self-stress -------------------------------------

def _braced_pair():
    """Two 4-bars of the chain (nodes 0..5) braced by a bar 1-5: one state of self-stress."""
    chain = fabkit.load_template("fourbar_chain").network
    x = _traced(chain, 2.3)[:6]
    edges = [e for e in chain.edges.tolist() if max(e) < 6] + [[1, 5]]
    ports = {"d2": (2, 3), "d3": (4, 5), "far": (0, 5), "cross": (1, 4), "bar": (2, 5)}
    return Network(x, edges, ports=ports), x


def _dual_and_vertices(x, edges, held, port, room):
    """The slop of a network with one self-stress, twice: (a) the least Σ c|λ + t w| over the
    line of solutions (its minimum is at a breakpoint), (b) the largest λ·s over the vertices of
    {|s| <= c, w·s = 0} (each on an edge of the box); and (c) the bound Σ c|λ0| of one λ."""
    r, h = _rows(x, edges), _rows(x, held)
    a = np.vstack([r, h])
    e = r.shape[0]
    left, sv, _ = np.linalg.svd(a)  # a is (E + H) × dN, one dependent row
    rank = int((sv > 1e-10 * sv[0]).sum())
    assert a.shape[0] - rank == 1, "expected exactly one state of self-stress"
    w_full = left[:, rank:][:, 0]
    w = w_full[:e]
    lam_full = np.linalg.lstsq(a.T, _rows(x, [port])[0], rcond=None)[0]
    lam0 = lam_full[:e]
    assert np.allclose(a.T @ lam_full, _rows(x, [port])[0], atol=1e-12)
    # (a) dual
    nz = np.abs(w) > 1e-12
    breaks = -lam0[nz] / w[nz]
    dual = min(float(np.abs(lam0 + t * w) @ room) for t in breaks)
    # (b) primal vertices: s_k free on an edge of the box, the others at ±c
    best = -np.inf
    for k in np.flatnonzero(nz):
        others = np.delete(np.arange(e), k)
        signs = np.array(list(itertools.product([-1.0, 1.0], repeat=e - 1)))
        s = np.zeros((len(signs), e))
        s[:, others] = signs * room[others]
        s[:, k] = -(s[:, others] @ w[others]) / w[k]
        ok = np.abs(s[:, k]) <= room[k] * (1 + 1e-12)
        if ok.any():
            best = max(best, float((s[ok] @ lam0).max()))
    return dual, best, float(np.abs(lam0) @ room)


def test_self_stress_compatibility_limits_the_slop():
    net, x = _braced_pair()
    room = np.array([0.3, 0.1, 0.2, 0.15, 0.05, 0.25, 0.1, 0.2, 0.02])
    held = [(0, 1)]  # the drive d1
    got = port_slop(net, x, room, held=held)
    assert [s.port for s in got] == list(net.ports)
    assert got[-1].largest == pytest.approx(room[5])  # a port that is a bar: its own room
    tighter = 0
    for s in got:
        dual, vertices, naive = _dual_and_vertices(x, net.edges, held, net.port(s.port), room)
        assert dual == pytest.approx(vertices, rel=1e-9)  # the two references agree
        assert s.increase == pytest.approx(dual, rel=1e-8)
        assert s.decrease == pytest.approx(dual, rel=1e-8)
        assert s.largest <= naive * (1 + 1e-12)
        tighter += s.largest < 0.95 * naive
    assert tighter >= 1  # compatibility matters for this network


# -- 4. a chain ----------------------------------------------------------------------------------

def test_chain_slop_grows_along_the_chain():
    chain = fabkit.load_template("fourbar_chain").network
    assert list(chain.ports) == ["d1", "d2", "d3", "d4", "d5"]
    x = 100.0 * chain.nodes  # 100 mm per design unit
    got = port_slop(chain, x, np.full(chain.n_edges, 0.2), held=[chain.port("d1")])
    assert [s.port for s in got] == ["d2", "d3", "d4", "d5"]  # the held drive left out
    values = [s.largest for s in got]
    assert all(s.bounded for s in got)
    assert all(a < b for a, b in zip(values, values[1:]))
    for s in got:
        lam = _lambda(x, chain.edges, [chain.port("d1")], chain.port(s.port))
        assert s.largest == pytest.approx(0.2 * float(np.abs(lam).sum()), rel=1e-9)
    # at d1 = 2.5 the ports alternate 2.5, 1.6, 2.5, ... (d_k·d_k+1 = 4): a module that shrinks
    # its port shrinks the play it inherits, so the slop in mm is not monotone; relative to the
    # port's distance it still grows along the chain
    x = 100.0 * _traced(chain, 2.5)
    got = port_slop(chain, x, np.full(chain.n_edges, 0.2), held=[chain.port("d1")])
    relative = [s.largest / float(chain.port_distance(s.port, x)) for s in got]
    assert all(a < b for a, b in zip(relative, relative[1:]))
    for s in got:
        lam = _lambda(x, chain.edges, [chain.port("d1")], chain.port(s.port))
        assert s.largest == pytest.approx(0.2 * float(np.abs(lam).sum()), rel=1e-9)


def test_the_result_is_in_the_unit_of_the_room():
    chain = fabkit.load_template("fourbar_chain").network
    held = [chain.port("d1")]
    unit = port_slop(chain, chain.nodes, 0.002, held=held)
    mm = port_slop(chain, 100 * chain.nodes, 0.2, held=held)
    assert [100 * s.largest for s in unit] == pytest.approx([s.largest for s in mm], rel=1e-9)


def test_ports_are_kept_in_the_order_given():
    chain = fabkit.load_template("fourbar_chain").network
    ports = {"last": chain.port("d5"), "first": chain.port("d2"), "drive": chain.port("d1")}
    got = port_slop(chain, chain.nodes, 0.01, held=[chain.port("d1")], ports=ports)
    assert [s.port for s in got] == ["last", "first", "drive"]
    assert got[2].largest == 0.0 and got[2].bounded  # a held pair does not move


# -- 5. unbounded: no drive held, a flat state ---------------------------------------------------

def test_a_mechanism_without_its_drive_is_unbounded():
    net = _fourbar()
    got = port_slop(net, net.nodes, 0.1)
    assert [s.port for s in got] == ["d1", "d2"]
    for s in got:
        assert not s.bounded and s.decrease == math.inf and s.increase == math.inf


def test_no_room_is_exactly_zero_but_a_free_port_stays_free():
    net = _fourbar()
    [held] = port_slop(net, net.nodes, np.zeros(4), held=[net.port("d1")])
    assert held.decrease == 0.0 and held.increase == 0.0 and held.bounded
    # boundedness does not depend on the room: without the drive, d2 wanders even with none
    [free] = port_slop(net, net.nodes, np.zeros(4), ports={"d2": net.port("d2")})
    assert not free.bounded


def test_a_flat_state_is_unbounded_and_near_it_the_slop_is_large():
    design = fabkit.load_template("physical_fourbar")
    net = design.network
    x = net.nodes
    a, b, p = x[0], x[1], x[2]  # node 2 on the line of nodes 0 and 1: flat with d1 held
    assert (b - a)[0] * (p - a)[1] - (b - a)[1] * (p - a)[0] == 0.0
    [flat] = port_slop(net, x, 0.1, held=[net.port("d1")])
    assert not flat.bounded and flat.largest == math.inf
    # held at d2 instead, the same state is regular: d1 (at its minimum there) has finite slop
    [d1] = port_slop(net, x, 0.1, held=[net.port("d2")])
    assert d1.bounded and d1.largest == pytest.approx(0.2, rel=1e-9)
    # off the flat state the first-order slop is finite, large, and grows as the state nears it
    traj = design.trace()
    near = []
    for k in (10, 5, 2, 1):
        xs = traj.positions[k]
        [s] = port_slop(net, xs, 0.1, held=[net.port("d1")])
        lam = _lambda(xs, net.edges, [net.port("d1")], net.port("d2"))
        assert s.largest == pytest.approx(0.1 * float(np.abs(lam).sum()), rel=1e-7)
        near.append(s.largest)
    assert all(u < v for u, v in zip(near, near[1:])) and near[-1] > 100 * 0.1


def test_beyond_the_amplification_limit_is_unbounded(monkeypatch):
    design = fabkit.load_template("physical_fourbar")
    net = design.network
    xs = design.trace().positions[1]
    [s] = port_slop(net, xs, 0.1, held=[net.port("d1")])
    assert s.bounded and 100 < s.largest / 0.1 < 1e4
    monkeypatch.setattr(slop_module, "MAX_AMPLIFICATION", 100.0)
    [s] = port_slop(net, xs, 0.1, held=[net.port("d1")])
    assert not s.bounded


# -- 6. bad input --------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, argument", [
    ({"room": np.full(3, 0.1)}, "room"),
    ({"room": np.full((4, 1), 0.1)}, "room"),
    ({"room": np.array([0.1, -0.1, 0.1, 0.1])}, "room"),
    ({"room": np.array([0.1, np.nan, 0.1, 0.1])}, "room"),
    ({"room": np.array([0.1, np.inf, 0.1, 0.1])}, "room"),
    ({"held": [(0, 4)]}, "held"),
    ({"held": [(-1, 2)]}, "held"),
    ({"held": [(1, 1)]}, "held"),
    ({"held": [(0, 1, 2)]}, "held"),
    ({"held": [(0.5, 1)]}, "held"),
    ({"ports": {"d9": (2, 9)}}, "ports"),
    ({"positions": np.zeros((3, 2))}, "positions"),
    ({"positions": np.full((4, 2), np.nan)}, "positions"),
])
def test_bad_arguments_are_named(kwargs, argument):
    net = _fourbar()
    args = {"positions": net.nodes, "room": np.full(4, 0.1), "held": [(0, 1)]} | kwargs
    with pytest.raises(ValueError, match=rf"^{argument}\b"):
        port_slop(net, args.pop("positions"), args.pop("room"), **args)


def test_bad_argument_messages_show_the_value():
    net = _fourbar()
    with pytest.raises(ValueError, match=r"room must have shape \(4,\).*got shape \(3,\)"):
        port_slop(net, net.nodes, np.full(3, 0.1))
    with pytest.raises(ValueError, match=r"room must be finite and >= 0, got -0.5 for bar 1"):
        port_slop(net, net.nodes, [0.1, -0.5, 0.1, 0.1])
    with pytest.raises(ValueError, match=r"held\[0\] names node 7, but the network has nodes 0..3"):
        port_slop(net, net.nodes, 0.1, held=[(0, 7)])
    with pytest.raises(TypeError, match=r"held .*net.port\('d1'\)"):
        port_slop(net, net.nodes, 0.1, held="d1")
    with pytest.raises(TypeError, match="net must be a fabkit.Network"):
        port_slop(net.nodes, net.nodes, 0.1)


def test_portslop_properties():
    s = PortSlop("d2", 0.1, 0.3)
    assert s.bounded and s.largest == 0.3
    assert not PortSlop("d2", math.inf, 0.3).bounded
