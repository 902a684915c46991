"""Named structures all the way down: the scripted loads, the Radau workspace and the Radau
step's arguments are named (numba-compatible NamedTuples), not a 6-tuple, slots read by
number or a 20-argument step."""
from __future__ import annotations

import inspect
from pathlib import Path

import numpy as np

from rod_sim.core import radau
from rod_sim.core.kernels import Control, Problem
from rod_sim.core.loadlaw import Loads
from rod_sim.core.models import load_table, make_model
from rod_sim.io.scene_yaml import load_scene

CONFIG = Path(__file__).resolve().parents[1] / "config"


def test_the_scripted_loads_are_a_named_table():
    scene = load_scene(CONFIG / "paper_example.yaml")
    loads = load_table(scene)
    assert isinstance(loads, Loads)
    assert loads._fields == ("row", "col", "shape", "amp", "start", "dur")
    np.testing.assert_array_equal(loads.row, [7, 7])         # node 8, both loads
    np.testing.assert_array_equal(loads.col, [0, 1])
    np.testing.assert_array_equal(loads.amp, [-150.0, 1200.0])


def test_the_radau_workspace_is_named_for_both_newton_algebras():
    model = make_model("full", load_scene(CONFIG / "deployment.yaml"))
    size = model.state_size
    for work in (radau.chain_radau_workspace(model), radau.radau_workspace(size)):
        assert isinstance(work, radau.RadauWork)
        assert work.Q.shape == (size, 3) and work.Z.shape == (3, size)
        assert work.ctl.shape == (radau.N_CTL,) and np.isnan(work.ctl[radau.RESUME_T])
    dense = radau.radau_workspace(size)
    m = size // 2
    assert dense.jac.shape == (m, 2 * m) and dense.real.shape == (m, m)
    assert dense.cplx.dtype == np.complex128 and dense.cplx_aux.dtype == np.int64
    rows = [radau.V_YY, radau.V_FD, radau.V_FR, radau.V_XR, radau.V_SCALE, radau.V_RHS_ERR,
            radau.V_ERR]
    assert len(set(rows)) == len(rows) and max(rows) < dense.V.shape[0]


def test_the_radau_step_takes_named_groups():
    params = list(inspect.signature(radau.advance_step.py_func).parameters)
    assert params == ["fns", "problem", "t_side", "t", "y", "f", "h", "t_bound", "control",
                      "work", "y_new", "f_new", "stats"]
    assert radau.RadauFns._fields == ("rhs", "jac", "factor", "solve")
    assert "control" in inspect.signature(radau.radau_run_work.py_func).parameters
    for fn in (radau.radau_run_work, radau.dense_jac, radau._newton):
        assert len(inspect.signature(fn.py_func).parameters) <= 10, fn
    assert Problem._fields == ("chain", "extra", "loads", "held")
    assert Control._fields[:2] == ("rtol", "atol")
