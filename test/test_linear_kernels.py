"""The O(n) kernels against the dense formulation they replaced (test/dense_kernels.py, the
oracle: the paper's matrices assembled entry by entry and solved by Gaussian elimination).

Random chains n = 1..64 with every hinge feature (rest angles, stop contacts on either side,
locked hinges, rigid rods, hinge motor moments, nodal forces, scripted loads): every model's
right-hand side agrees to 1e-12 relative; the O(n) inertia product, velocity projection,
kinetic energy and quasi-static bending agree with their dense counterparts; the compliant
(shifted) solve that the eigenvalue search uses solves (M + s K) x = f."""
from __future__ import annotations

import numpy as np
import pytest

from rod_sim.core import kernels, linearization
from rod_sim.core.matrices import ChainParams, full_system, reduced_system
from rod_sim.core.models import make_model
from rod_sim.core.scene import Load, Scene

from dense_kernels import (constraint_basis, constraint_matrix, dense_mass_matrix,
                           dense_reduced_mass, dense_rhs)

MODELS = ("rigid", "reduced", "full")


def random_scene(n: int, rng, features: bool) -> Scene:
    kw = dict(name="random", length=rng.uniform(0.3, 2.0, n),
              mass_per_length=rng.uniform(0.5, 3.0, n),
              bending_stiffness=rng.uniform(50.0, 5e3, n), node_mass=rng.uniform(0.0, 1.0, n),
              hinge_stiffness=rng.uniform(0.0, 50.0, n), hinge_damping=rng.uniform(0.0, 2.0, n),
              phi0=rng.uniform(-1.0, 1.0, n), phi_rate0=rng.uniform(-1.0, 1.0, n),
              loads=(Load(node=n, axis="y", shape="constant", amplitude=3.0),
                     Load(node=1, axis="x", shape="raised_cosine_pulse", amplitude=-2.0,
                          start=0.0, duration=0.5)))
    if features:
        kw.update(hinge_rest_angle=rng.uniform(-0.3, 0.3, n), stop_lower=np.full(n, -0.2),
                  stop_upper=np.full(n, 0.2), stop_stiffness=rng.uniform(10.0, 1e3, n),
                  stop_damping=rng.uniform(0.0, 5.0, n),
                  hinge_locked=rng.uniform(size=n) < 0.3, rod_rigid=rng.uniform(size=n) < 0.3)
    return Scene(**kw)


def _cases(seed=11, count=40):
    rng = np.random.default_rng(seed)
    for i in range(count):
        n = int(rng.choice([1, 2, 3, 5, 8, 13, 21, 34, 64])) if i > 2 else i + 1
        yield n, rng, i % 2 == 1


def _rel(a, b):
    return float(np.max(np.abs(a - b)) / max(1e-300, np.max(np.abs(b))))


@pytest.mark.slow
@pytest.mark.parametrize("model_name", MODELS)
def test_rhs_equals_the_dense_formulation_with_every_hinge_feature(model_name):
    worst = 0.0
    features_seen = set()
    for n, rng, features in _cases():
        sc = random_scene(n, rng, features)
        m = make_model(model_name, sc)
        y = m.initial_state() + 0.2 * rng.normal(size=m.state_size)
        held = rng.normal(size=(n, 3)) * [5.0, 5.0, 2.0]
        locked = np.asarray(sc.hinge_locked, bool)
        side = rng.integers(-1, 2, n).astype(np.int8) if features else np.zeros(n, np.int8)
        if features:
            features_seen |= {"locked"} if locked.any() else set()
            features_seen |= {"rigid"} if np.any(sc.rod_rigid) else set()
            features_seen |= {"contact"} if np.any(side[~locked] != 0) else set()
        got = m.rhs(0.2, y, held, None, side)
        want = dense_rhs(model_name, sc, 0.2, y, held, locked, side)
        assert np.all(np.isfinite(want))
        worst = max(worst, _rel(got, want))
    assert worst < 1e-12, worst
    assert features_seen == {"locked", "rigid", "contact"}


def test_the_oracle_is_the_paper_transcription():
    """The dense oracle itself against matrices.py (the paper's formulas as printed)."""
    rng = np.random.default_rng(5)
    sc = random_scene(7, rng, False).with_changes(loads=())
    p = ChainParams.from_scene(sc)
    forces = np.zeros((7, 2))
    q, qd = rng.normal(size=21) * 0.3, rng.normal(size=21)
    M, F = full_system(p, q, qd, forces)
    y = np.concatenate([q, qd])
    np.testing.assert_allclose(dense_rhs("full", sc, 0.0, y)[21:], np.linalg.solve(M, F),
                               rtol=1e-10, atol=1e-10)
    Mr, Fr, _ = reduced_system(p, q[:7], qd[:7], forces)
    y = np.concatenate([q[:7], qd[:7]])
    np.testing.assert_allclose(dense_rhs("reduced", sc, 0.0, y)[7:], np.linalg.solve(Mr, Fr),
                               rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("model_name", MODELS)
def test_inertia_product_projection_and_kinetic_energy(model_name):
    for n, rng, features in _cases(seed=3, count=12):
        sc = random_scene(n, rng, features)
        m = make_model(model_name, sc)
        y = m.initial_state() + 0.2 * rng.normal(size=m.state_size)
        d = m.dof
        phi = y[:n]
        p = ChainParams.from_scene(sc)
        Mfull, _ = full_system(p, np.concatenate([phi, np.zeros(2 * n)]), np.zeros(3 * n),
                               np.zeros((n, 2)))
        M = Mfull[:d, :d]
        np.testing.assert_allclose(dense_mass_matrix(m, y), M, rtol=1e-12, atol=1e-12)
        assert abs(m.kinetic_energy(0.0, y) - 0.5 * y[d:] @ M @ y[d:]) < 1e-12 * (
            1 + abs(y[d:] @ M @ y[d:]))
        mode = rng.uniform(size=n) < 0.5
        locked = np.asarray(sc.hinge_locked, bool) | mode
        C = constraint_matrix(sc, m.dof_per_rod, locked)
        y1 = m.project_velocity(y, mode)
        if C.shape[0] == 0:
            np.testing.assert_array_equal(y1, y)
            continue
        order = (list(range(n, 3 * n)) if m.dof_per_rod == 3 else []) + list(range(n - 1, -1, -1))
        T = constraint_basis(C, order)
        if model_name == "reduced":
            M = dense_reduced_mass(sc, phi)
        v = y[d:]
        want = T @ np.linalg.solve(T.T @ M @ T, T.T @ (M @ v))
        np.testing.assert_allclose(y1[d:], want, rtol=1e-10, atol=1e-10 * np.max(np.abs(v)))
        np.testing.assert_allclose(C @ y1[d:], 0.0, atol=1e-10 * np.max(np.abs(v)))


def test_reduced_bending_is_gamma_of_eq_14():
    rng = np.random.default_rng(8)
    for n in (1, 4, 17):
        sc = random_scene(n, rng, False).with_changes(loads=())
        m = make_model("reduced", sc)
        y = m.initial_state() + 0.2 * rng.normal(size=2 * n)
        p = ChainParams.from_scene(sc)
        Mr, Fr, gamma = reduced_system(p, y[:n], y[n:], np.zeros((n, 2)))
        g = gamma(np.linalg.solve(Mr, Fr))
        a, b = m.bending(0.0, y)
        np.testing.assert_allclose(np.concatenate([a, b]), g, rtol=1e-10,
                                   atol=1e-12 * np.max(np.abs(g)))


@pytest.mark.parametrize("locked_rigid", [False, True])
def test_shifted_solve_is_m_plus_s_k(locked_rigid):
    rng = np.random.default_rng(21)
    for n in (1, 3, 9):
        sc = random_scene(n, rng, False)
        if locked_rigid:
            sc = sc.with_changes(hinge_locked=np.arange(n) % 3 == 1, rod_rigid=np.arange(n) == 0)
        m = make_model("full", sc)
        phi = sc.phi0
        for s in (-1e-3, 2.5e-4):
            d = 3 * n
            eye = np.eye(d)
            M = np.column_stack([linearization.mass_times(m, phi, eye[i]) for i in range(d)])
            K = np.column_stack([linearization.stiffness_times(m, eye[i]) for i in range(d)])
            f = rng.normal(size=d)
            x = linearization.shifted_solver(m, phi, s)(f)
            C = constraint_matrix(sc, 3, np.asarray(sc.hinge_locked, bool))
            A = M + s * K
            if C.shape[0]:
                # x on the constraint set and A x - f along C^T
                np.testing.assert_allclose(C @ x, 0.0, atol=1e-10)
                T = constraint_basis(C, list(range(n, 3 * n)) + list(range(n - 1, -1, -1)))
                np.testing.assert_allclose(T.T @ (A @ x - f), 0.0, atol=1e-8)
            else:
                np.testing.assert_allclose(A @ x, f, rtol=1e-9, atol=1e-9)


def test_no_n_by_n_array_in_a_model():
    """Memory is O(n): nothing a model keeps (chain constants, plans' arrays) grows as n^2."""
    for n in (64, 256):
        sc = random_scene(n, np.random.default_rng(0), True)
        for name in MODELS:
            m = make_model(name, sc)
            m.rhs(0.0, m.initial_state())
            arrays = list(m.chain) + [a for a in m.plan().extra if isinstance(a, np.ndarray)]
            assert max(a.size for a in arrays) <= kernels.N_WORK * n + kernels.N_SMALL
