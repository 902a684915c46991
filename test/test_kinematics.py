"""Node positions (3) and bent-rod points (4) as printed in the paper."""
import numpy as np

from rod_sim.core.kinematics import node_positions, rod_points, shape_functions


def test_points_follow_eq_4_as_printed_and_end_slopes_are_alpha_beta():
    rng = np.random.default_rng(7)
    n, P = 5, 41
    l = rng.uniform(0.5, 2.0, n)
    phi = rng.uniform(-3, 3, n)
    alpha, beta = rng.normal(0, 0.05, n), rng.normal(0, 0.05, n)
    nodes = node_positions(l, phi)
    # eq. (3)
    assert np.allclose(nodes[1:, 0], np.cumsum(l * np.cos(phi)))
    assert np.allclose(nodes[1:, 1], np.cumsum(l * np.sin(phi)))
    assert np.all(nodes[0] == 0.0)
    pts = rod_points(l, phi, alpha, beta, P)
    for k in range(n):
        s = np.linspace(0, l[k], P)
        eta = alpha[k] * s * (l[k] - s) ** 2 / l[k] ** 2 - beta[k] * s**2 * (l[k] - s) / l[k] ** 2
        # eq. (4): measured back from node k
        x = nodes[k + 1, 0] - (l[k] - s) * np.cos(phi[k]) - eta * np.sin(phi[k])
        y = nodes[k + 1, 1] - (l[k] - s) * np.sin(phi[k]) + eta * np.cos(phi[k])
        assert np.allclose(pts[k, :, 0], x, atol=1e-12) and np.allclose(pts[k, :, 1], y, atol=1e-12)
        # the rods end on their nodes
        assert np.allclose(pts[k, 0], nodes[k]) and np.allclose(pts[k, -1], nodes[k + 1])
    # sigma'(0) = 1, sigma'(l) = 0, tau'(0) = 0, tau'(l) = 1: alpha, beta are the end slopes
    L, h = 1.7, 1e-6
    for s0, want_sigma, want_tau in ((0.0, 1.0, 0.0), (L, 0.0, 1.0)):
        a = np.array([s0 - h, s0 + h]) if 0 < s0 < L else (np.array([s0, s0 + h]) if s0 == 0 else np.array([s0 - h, s0]))
        sig, tau = shape_functions(a, L)
        assert abs((sig[1] - sig[0]) / (a[1] - a[0]) - want_sigma) < 1e-5
        assert abs((tau[1] - tau[0]) / (a[1] - a[0]) - want_tau) < 1e-5


def test_chain_sums_are_each_chains_cumsum_bit_for_bit():
    """chain_cumsum / chain_nodes (no loop over chains) give the values of np.cumsum over
    each chain's slice plus its node 0, bit for bit, for chains of equal and unequal lengths
    (signed zeros included)."""
    from rod_sim.core.kinematics import chain_cumsum, chain_nodes, chain_table

    rng = np.random.default_rng(5)
    for counts in ((1,), (7,), (3, 3), (2, 9, 5), (12, 1, 12, 4), (16, 16, 16)):
        seg = np.concatenate([[0], np.cumsum(counts)])
        n, nc = seg[-1], len(counts)
        table = chain_table(seg)
        steps = rng.normal(size=(n, 2)) * 10.0 ** rng.integers(-8, 8, size=(n, 2))
        steps[rng.random((n, 2)) < 0.2] = -0.0
        origin = rng.normal(size=(nc, 2))
        origin[0] = -0.0
        want = np.empty((n + nc, 2))
        for c in range(nc):
            a, b = seg[c], seg[c + 1]
            want[a + c] = origin[c]
            want[a + c + 1:b + c + 1] = origin[c] + np.cumsum(steps[a:b], axis=0)
            assert chain_cumsum(steps, table)[a:b].tobytes() == \
                np.cumsum(steps[a:b], axis=0).tobytes()
        assert chain_nodes(origin, steps, table).tobytes() == want.tobytes()
