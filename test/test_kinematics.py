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
