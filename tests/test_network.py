"""Network construction: validation errors name the offending node or edge."""

import numpy as np
import pytest

import fabkit
from fabkit import Network, NetworkError


def test_basic_properties(fourbar):
    assert fourbar.dim == 2 and fourbar.n_nodes == 4 and fourbar.n_edges == 4
    np.testing.assert_allclose(fourbar.edge_lengths, [2, 2 * np.sqrt(2), 2 * np.sqrt(2), 2])
    assert float(fourbar.port_distance("d1")) == pytest.approx(2.0)
    assert fourbar.nodes.dtype == np.float64
    with pytest.raises(ValueError):
        fourbar.nodes[0, 0] = 5.0  # immutable


def test_port_distance_over_stack(fourbar):
    stack = np.stack([fourbar.nodes, 2 * fourbar.nodes])
    np.testing.assert_allclose(fourbar.port_distance("d2", stack), [2.0, 4.0])
    np.testing.assert_allclose(fourbar.edge_error(stack), [0.0, 1.0])


def test_unknown_port_lists_known(fourbar):
    with pytest.raises(KeyError, match="d1, d2"):
        fourbar.port("d7")


@pytest.mark.parametrize(
    "nodes, edges, ports, match",
    [
        ([[0, 0], [1, np.nan]], [[0, 1]], {}, "node 1 has a non-finite coordinate"),
        ([[0, 0], [1, np.inf]], [[0, 1]], {}, "node 1"),
        ([[0, 0, 0, 0], [1, 0, 0, 0]], [[0, 1]], {}, r"shape \(N, 2\) or \(N, 3\), got \(2, 4\)"),
        ([[0, 0], [1, 0]], [[0, 2]], {}, r"edge 0 \[0, 2\] names a node outside 0..1"),
        ([[0, 0], [1, 0]], [[-1, 1]], {}, "edge 0"),
        ([[0, 0], [1, 0]], [[1, 1]], {}, "edge 0 joins node 1 to itself"),
        ([[0, 0], [1, 0], [0, 1]], [[0, 1], [1, 2], [1, 0]], {}, "edges 0 and 2 both join nodes 0 and 1"),
        ([[0, 0], [1, 0], [1, 0]], [[0, 1], [1, 2]], {}, r"edge 1 \[1, 2\] has zero length"),
        ([[0, 0], [1, 0]], [[0, 1.5]], {}, "non-integer node index"),
        ([[0, 0], [1, 0]], [[0, 1, 2]], {}, r"`edges` must have shape \(E, 2\)"),
        ([[0, 0], [1, 0], [2, 0]], [[0, 1]], {"d1": (0, 5)}, "port 'd1' names node 5"),
        ([[0, 0], [1, 0], [2, 0]], [[0, 1]], {"d1": (2, 2)}, "port 'd1' joins node 2 to itself"),
        ([[0, 0]], [], {}, "at least 2 nodes"),
    ],
)
def test_validation_errors(nodes, edges, ports, match):
    with pytest.raises(NetworkError, match=match):
        Network(nodes, edges, ports)


def test_errors_are_fabkit_errors():
    with pytest.raises(fabkit.FabkitError):
        Network([[0, 0], [0, 0]], [[0, 1]])


@pytest.mark.parametrize("nodes, edges, ports, key", [
    ([[0, 0], [1, 0], [np.nan, 1]], [[0, 1]], {}, "nodes[2]"),
    ([[0, 0], [1, 0], [0, 1]], [[0, 1], [1, 1]], {}, "edges[1]"),
    ([[0, 0], [1, 0], [0, 1]], [[0, 1], [1, 2], [1, 0]], {}, "edges[0]"),
    ([[0, 0], [1, 0], [0, 1]], [[0, 1]], {"d1": (0, 7)}, "ports.d1"),
    ([[0, 0, 0, 0], [1, 0, 0, 0]], [[0, 1]], {}, "nodes"),
])
def test_network_errors_name_the_key_at_fault(nodes, edges, ports, key):
    # callers (the template reader) point at the key from this field, never from the message
    with pytest.raises(NetworkError) as info:
        Network(nodes, edges, ports=ports)
    assert info.value.key == key


def test_a_chain_port_is_d_and_ascii_digits():
    from fabkit.model.network import chain_port_number, is_chain_port

    assert [chain_port_number(p) for p in ("d1", "d12", "d007", "d", "d1_b", "d²", "d١", "x1")] \
        == [1, 12, 7, None, None, None, None, None]
    assert is_chain_port("d3") and not is_chain_port("d²") and not is_chain_port(3)
