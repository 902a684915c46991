"""The torque <-> force helpers of rod_sim.ros.controller as a public API (issue 20 item 2's
independent part): hinge_torques is the virtual work of nodal forces per hinge angle (checked
against finite differences of the node positions, not against the formula), hinge_forces
realises given hinge torques, and the example of docs/node.md runs."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from rod_sim.ros.controller import hinge_forces, hinge_torques

REPO = Path(__file__).resolve().parents[1]


def nodes(q, lengths) -> np.ndarray:
    """Node positions (n, 2) of nodes 1..n for relative hinge angles q (hinge 0 absolute)."""
    phi = np.cumsum(q)
    return np.cumsum(np.stack([lengths * np.cos(phi), lengths * np.sin(phi)], axis=1), axis=0)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_hinge_torques_is_the_virtual_work_of_the_forces(seed):
    rng = np.random.default_rng(seed)
    n = 7
    q = rng.uniform(-1.0, 1.0, n)
    lengths = rng.uniform(0.3, 2.0, n)
    forces = rng.normal(scale=10.0, size=(n, 2))
    h = 1e-6
    numeric = np.array([np.sum(forces * (nodes(q + h * e, lengths) - nodes(q - h * e, lengths)))
                        / (2 * h) for e in np.eye(n)])
    got = hinge_torques(forces, np.cumsum(q), lengths)
    np.testing.assert_allclose(got, numeric, rtol=1e-7, atol=1e-7)
    np.testing.assert_array_equal(got, hinge_torques(forces.ravel(), np.cumsum(q), lengths))


def test_hinge_forces_realise_the_torques_and_chord_forces_have_none():
    rng = np.random.default_rng(4)
    n = 5
    phi = rng.uniform(-3.0, 3.0, n)
    lengths = rng.uniform(0.5, 1.5, n)
    moments = rng.normal(size=n)
    np.testing.assert_allclose(hinge_torques(hinge_forces(moments, phi, lengths), phi, lengths),
                               moments, atol=1e-12)
    one = np.zeros((n, 2))
    one[2] = 3.0 * np.array([np.cos(phi[2]), np.sin(phi[2])])   # along rod 3's chord at node 3
    along = hinge_torques(one, phi, lengths)
    np.testing.assert_allclose(along[2:], 0.0, atol=1e-12)      # hinges 2.. do not feel it
    assert np.all(np.abs(along[:2]) > 1e-6)                     # hinges 0, 1 do
    # a single moment at the root hinge of a one-rod chain: the force T / l at the tip, normal
    np.testing.assert_allclose(hinge_forces([2.0], [0.0], [4.0]), [[0.0, 0.5]])


def test_the_documented_example_runs():
    text = (REPO / "docs" / "node.md").read_text()
    block = re.search(r"^```python\n(from rod_sim\.ros\.controller import.*?)^```", text,
                      re.M | re.S)
    assert block, "docs/node.md shows the helpers"
    namespace: dict = {}
    exec(compile(block.group(1), "docs/node.md", "exec"), namespace)      # its asserts hold
    assert list(namespace["command"].data) == namespace["forces"].ravel().tolist()
