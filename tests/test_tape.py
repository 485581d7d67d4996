"""The model's instruction tape (model/tape.py) and its compiled interpreters against the
generated NumPy functions (SPEC 1, 5).

The NumPy functions come from the same definitions (``derive.derive``) through SymPy's
printer, while the tape is built by another translation (value numbering, sines and cosines
by angle addition, products folded into sums); the derivation itself is checked against the
reference derivation and an independent computation in ``test_parametric_model.py`` and
``test_model.py``. Every program of the tape, on both bundled robots and a robot without
thrusters, at 1, 33 and 200 states (the batch interpreter works in chunks of 64), and the
scalar interpreter of the compiled kernel against the batch one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from thrustwalk_cli.files.robot_file import load_robot
from thrustwalk_cli.model import jit
from thrustwalk_cli.model.compiler import load_model

BARE = str(Path(__file__).parent / "data" / "three_link_bare.yaml")


@pytest.fixture(scope="module", params=["three_link", "rabbit", "bare"])
def model(request, _cache_dir):
    return load_model(load_robot(BARE if request.param == "bare" else request.param))


def _states(model, k: int, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.2, 1.2, (k, model.n)), rng.uniform(-3.0, 3.0, (k, model.n))


def _expected(model, program: str, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
    """The program's outputs from the generated NumPy functions (flat, row-major)."""
    k, n = q.shape
    flat = lambda a: a.reshape(k, -1)  # noqa: E731
    dqu = np.concatenate([dq, np.zeros((k, 2))], axis=1)
    accel = [flat(model.D(q)), flat(model.h(q, dq)), flat(model.B_F(q))]
    if program == "accel":
        parts = accel
    elif program == "force":
        parts = accel + [flat(model.D_u(q)[:, n:, :n]), flat(model.h_u(q, dqu)[:, n:]),
                         flat(model.B_Fu(q)[:, n:, :])]
    elif program == "height":
        parts = [flat(model.p_swing(q))]
    elif program == "footvel":
        parts = [np.einsum("kj,kj->k", model.E_swing(q)[:, 1, :], dq)[:, None]]
    elif program == "links":
        parts = [flat(model.link_points(q))]
    elif program == "impact":
        parts = [flat(model.D_u(q)), flat(model.E_swing_u(q))]
    elif program == "energy":
        parts = [flat(model.D(q)), flat(model.V(q))]
    else:
        parts = [flat(model.D(q)), flat(model.link_points_J(q))]
    return np.concatenate(parts, axis=1)


@pytest.mark.parametrize("k", [1, 33, 200])
@pytest.mark.parametrize("program", ["accel", "force", "height", "footvel", "links",
                                     "impact", "energy", "push"])
def test_every_program_equals_the_generated_numpy_functions(model, program, k):
    q, dq = _states(model, k)
    n_in = int(model.tape.code[model.tape.programs[program]])
    got = jit.run_batch(model, program, np.concatenate([q, dq], axis=1)[:, :n_in])
    want = _expected(model, program, q, dq)
    assert got.shape == want.shape, program
    scale = np.maximum(np.abs(want).max(axis=0), 1.0)
    err = np.abs(got - want) / scale
    assert err.max() < 1e-12, (program, np.unravel_index(err.argmax(), err.shape))


def test_D_h_batch_equals_the_numpy_path(model):
    """``jit.D_h_batch`` (the compiled batch D and C q' + G, SPEC 1) at 257 states."""
    q, dq = _states(model, 257, seed=11)
    D, h = jit.D_h_batch(model, q, dq)
    np.testing.assert_allclose(D, model.D(q), rtol=1e-13, atol=1e-12)
    np.testing.assert_allclose(h, model.h(q, dq), rtol=1e-12, atol=1e-11)
    # one state, given as 1-D arrays
    D1, h1 = jit.D_h_batch(model, q[5], dq[5])
    np.testing.assert_array_equal(D1[0], D[5])
    np.testing.assert_array_equal(h1[0], h[5])


def test_scalar_interpreter_of_the_kernel_equals_the_batch_interpreter(model):
    """``tape_run`` (one state, inside the compiled simulation) and ``tape_batch`` execute
    the same instructions: equal to the last bit."""
    from thrustwalk_cli.simulation.stepper import kernel

    run = kernel().module.tape_run
    tape = model.tape
    q, dq = _states(model, 7, seed=5)
    x_all = np.concatenate([q, dq], axis=1)
    for program, p in tape.programs.items():
        batch = jit.run_batch(model, program, x_all[:, :int(tape.code[p])])
        n_out = tape.n_out(program)
        r = np.concatenate([tape.registers(), np.zeros(n_out)])  # outputs after the registers
        for i in range(len(q)):
            run(tape.code, p, np.ascontiguousarray(x_all[i]), r, tape.nreg)
            np.testing.assert_array_equal(r[tape.nreg:], batch[i], err_msg=program)


def test_tape_layout(model):
    """Registers: inputs (2N), constants, then one per instruction; the summary counts
    them."""
    tape = model.tape
    assert tape.n_inputs == 2 * model.n
    assert set(tape.programs) == {"accel", "force", "height", "footvel", "links", "impact",
                                  "energy", "push"}
    longest = max(tape.instructions(p) for p in tape.programs)
    assert tape.nreg == tape.n_inputs + tape.consts.size + longest
    s = model.summary()["tape"]
    assert s["instructions"] == sum(tape.instructions(p) for p in tape.programs)
    assert s["instructions_accel"] == tape.instructions("accel") > 0
