"""Compiled numeric robot models (SPEC section 1): generated functions plus derived maps.

A :class:`CompiledModel` evaluates one state (shape ``(N,)``) or a batch (shape ``(..., N)``)
without Python loops over states:

    D(q) q'' + C(q, q') q' + G(q) = B_tau u + B_F(q) F_T        (pinned, SPEC 1)
    h(q, q') = C(q, q') q' + G(q)

Unpinned quantities (``q_u = [q; x_1; y_1]``) do not depend on the foot position, so they
take ``q`` (N) and, where needed, ``dq_u`` (N+2). Models are built and cached by
:mod:`thrustwalk_cli.model.compiler`; loading a cached model never imports SymPy.

The generated code takes the robot's numbers (``Robot.numbers()``) as inputs: a
:class:`CompiledModel` binds one robot's numbers to it (its functions are closures over the
coefficients computed from them, and its tape carries them as constants), so callers write
``model.D(q)`` whatever the robot, and robots differing only in their numbers share the
generated code, the tape's instructions and the compiled kernel.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from ..description.robot import Robot
from .tape import Tape

# name -> (argument list, doc) of every generated function
FUNCTIONS: dict[str, tuple[tuple[str, ...], str]] = {
    "D": (("q",), "Pinned inertia matrix D(q) [kg m^2], SPEC 1."),
    "C": (("q", "dq"), "Coriolis matrix C(q, q') from Christoffel symbols [kg m^2/s], SPEC 1."),
    "G": (("q",), "Gravity vector G = dV/dq [N m], SPEC 1."),
    "h": (("q", "dq"), "Bias h = C(q, q') q' + G(q) [N m], SPEC 1."),
    "V": (("q",), "Potential energy V(q) [J]."),
    "B_F": (("q",), "Thruster input matrix B_F(q) = [J_k^T d_k] [m], SPEC 1."),
    "D_u": (("q",), "Unpinned inertia matrix D_u(q), q_u = [q; x1; y1], SPEC 1."),
    "h_u": (("q", "dq_u"), "Unpinned bias C_u q_u' + G_u, SPEC 1/5."),
    "C_u": (("q", "dq_u"), "Unpinned Coriolis matrix C_u(q, q_u'), SPEC 1."),
    "B_Fu": (("q",), "Unpinned thruster map B_Fu(q), SPEC 1."),
    "p_swing": (("q",), "Swing-foot position p_2 relative to the stance foot [m]."),
    "E_swing": (("q",), "Swing-foot Jacobian dp_2/dq [m]."),
    "E_swing_u": (("q",), "Swing-foot Jacobian E_2 = dp_2/dq_u (2 x (N+2)), SPEC 1."),
    "p_com": (("q",), "Centre of mass relative to the stance foot [m]."),
    "J_com": (("q",), "Centre-of-mass Jacobian [m]."),
    "thruster_points": (("q",), "Thruster application points p_k, columns [m]."),
    "thruster_dirs": (("q",), "Thruster unit directions d_k in the world, columns."),
    "link_points": (("q",), "Per link: frame origin (x, y) and end point (x, y) [m]."),
    "link_points_J": (("q",), "Jacobian d(link_points)/dq (4 rows per link) [m]."),
}



VECTORS = {"G", "h", "V", "h_u", "p_swing", "p_com", "link_points"}


@dataclass(frozen=True)
class ImpactResult:
    """Rigid impact of the swing foot (SPEC 5), for one state or a batch.

    dq_plus: post-impact rates after relabelling, ``R Delta_q'(q^-) q'^-`` [rad/s].
    q_plus: relabelled configuration ``R q^- + b`` [rad].
    dq_u_plus: unpinned post-impact rates before relabelling, ``[q'; x'; y']`` (the last two
    are the velocity of the old stance foot, which must lift off: ``y' > 0``) [rad/s, m/s].
    impulse: ground impulse ``F_2`` on the new stance foot (x, y) [N s].
    """

    q_plus: np.ndarray
    dq_plus: np.ndarray
    dq_u_plus: np.ndarray
    impulse: np.ndarray


class CompiledModel:
    """A robot description plus its generated numeric functions, bound to its numbers.

    The description is immutable; per-run buffers never live here. Raises ``ImportError``
    when the generated module does not provide what the robot needs (a broken cache entry:
    the compiler rebuilds it).
    """

    def __init__(self, robot: Robot, module: ModuleType, path: Path | None, key: str,
                 cache_hit: bool, seconds: float, notes: tuple[str, ...] = ()):
        self.robot = robot
        self._m = module
        numbers = robot.numbers()
        if list(getattr(module, "PARAMS", ())) != [name for name, _ in numbers]:
            raise ImportError("the generated model's inputs are not this robot's numbers")
        #: the robot's numbers bound to the generated code, in the order of
        #: ``Robot.numbers()`` (SI units)
        self.numbers = np.array([v for _, v in numbers], float)
        self.numbers.setflags(write=False)
        fns = module.bind(self.numbers.tolist())
        missing = [f for name in FUNCTIONS for f in (name, name + "_s") if f not in fns]
        if missing or "_consts" not in fns or not hasattr(module, "TAPE"):
            raise ImportError(f"functions missing: {', '.join(missing) or 'TAPE'}")
        #: the cache entry, or None when the model lives only in memory (see ``notes``)
        self.cache_path = path
        #: one-line remarks about the cache (an entry rebuilt, the cache unusable)
        self.notes = tuple(notes)
        self.key = key
        self.cache_hit = cache_hit
        self.load_seconds = seconds
        self.n = robot.n
        self.n_thrusters = len(robot.thrusters)
        self.R = robot.R
        self.b = robot.b
        self.B_tau = np.vstack([np.eye(self.n - 1), np.zeros((1, self.n - 1))])
        for name in FUNCTIONS:
            setattr(self, name, fns[name])
            setattr(self, name + "_s", fns[name + "_s"])
        #: the model as instruction tapes for the compiled interpreter (model/tape.py): the
        #: instructions of the robot's structure (shared), the constants of its numbers
        self.tape = Tape.from_data(module.TAPE, fns["_consts"])

    def __repr__(self) -> str:
        """One line: the robot, its number of links, its thrusters and the cache entry (a
        model holds generated functions and tapes, which a notebook should not print)."""
        entry = str(self.cache_path) if self.cache_path else "in memory"
        return (f"CompiledModel(robot={self.robot.name!r}, links={len(self.robot.links)}, "
                f"thrusters={self.robot.thruster_names!r}, cache={entry!r})")

    # -- derived quantities ----------------------------------------------------------------
    def energy(self, q: np.ndarray, dq: np.ndarray, D: np.ndarray | None = None
               ) -> np.ndarray:
        """Mechanical energy ``1/2 q'^T D q' + V`` [J] (pinned); ``D``: ``D(q)`` when the
        caller has it already."""
        q, dq = np.asarray(q, float), np.asarray(dq, float)
        K = 0.5 * np.einsum("...i,...ij,...j->...", dq, self.D(q) if D is None else D, dq)
        return K + self.V(q)[..., 0]

    def relabel(self, q: np.ndarray) -> np.ndarray:
        """``q^+ = R q^- + b`` (SPEC 1)."""
        return np.asarray(q, float) @ self.R.T + self.b

    def impact_maps(self, q_minus: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Linear impact maps at ``q^-`` (SPEC 5), shapes ``(..., N+2, N)`` and ``(..., 2, N)``.

        Returns ``(M_u, M_F, Delta)``: ``q_u'^+ = M_u q'^-`` (before relabelling),
        ``F_2 = M_F q'^-``, and ``Delta = M_u[:N]`` (``Delta_q'`` of SPEC 1).
        From ``[D_u, -E_2^T; E_2, 0][q_u'^+; F_2] = [D_u q_u'^-; 0]`` with ``q_u'^- = [q'^-; 0]``:
        ``F_2 = -(E_2 D_u^-1 E_2^T)^-1 E_2 [I_N; 0] q'^-``,
        ``q_u'^+ = [I_N; 0] q'^- + D_u^-1 E_2^T F_2``.
        """
        q = np.asarray(q_minus, float)
        n = self.n
        Du = self.D_u(q)
        E = self.E_swing_u(q)
        Et = np.swapaxes(E, -1, -2)
        DinvEt = np.linalg.solve(Du, Et)  # (..., N+2, 2)
        S = E @ DinvEt  # (..., 2, 2)
        MF = -np.linalg.solve(S, E[..., :, :n])  # (..., 2, N)
        I = np.zeros(q.shape[:-1] + (n + 2, n))
        I[..., np.arange(n), np.arange(n)] = 1.0
        Mu = I + DinvEt @ MF
        return Mu, MF, Mu[..., :n, :]

    def impact(self, q_minus: np.ndarray, dq_minus: np.ndarray) -> ImpactResult:
        """Apply the impact map and relabelling to pre-impact states (SPEC 1, 5)."""
        q = np.asarray(q_minus, float)
        dq = np.asarray(dq_minus, float)
        Mu, MF, _ = self.impact_maps(q)
        dqu = np.einsum("...ij,...j->...i", Mu, dq)
        F2 = np.einsum("...ij,...j->...i", MF, dq)
        return ImpactResult(
            q_plus=self.relabel(q),
            dq_plus=dqu[..., : self.n] @ self.R.T,
            dq_u_plus=dqu,
            impulse=F2,
        )

    def evaluate_state(self, q, dq=None, thrust=None) -> dict:
        """Plain numbers at one state (for ``inspect``): D, C q', G, B_F, swing foot, impact."""
        q = np.asarray(q, float)
        out: dict = {"D": self.D(q).tolist(), "G": self.G(q).tolist(),
                     "B_F": self.B_F(q).tolist(), "swing_foot": self.p_swing(q).tolist(),
                     "com": self.p_com(q).tolist(), "potential_energy": float(self.V(q)[0])}
        if dq is not None:
            dq = np.asarray(dq, float)
            out["dq"] = dq.tolist()
            out["C_dq"] = (self.C(q, dq) @ dq).tolist()
            out["kinetic_energy"] = float(0.5 * dq @ self.D(q) @ dq)
            imp = self.impact(q, dq)
            out["impact"] = {"q_plus": imp.q_plus.tolist(), "dq_plus": imp.dq_plus.tolist(),
                             "impulse": imp.impulse.tolist(),
                             "old_stance_foot_velocity": imp.dq_u_plus[self.n:].tolist()}
        if thrust is not None:
            out["thrust"] = list(map(float, thrust))
            out["B_F_thrust"] = (self.B_F(q) @ np.asarray(thrust, float)).tolist()
        return out

    def summary(self) -> dict:
        """Plain description for tables and JSON."""
        r = self.robot
        return {
            "name": r.name,
            "links": len(r.links),
            "coordinates": r.coordinate_names,
            "actuated": [c.name for c in r.coordinates if c.actuated],
            "unactuated": next(c.name for c in r.coordinates if not c.actuated),
            "total_mass": r.total_mass,
            "thrusters": r.thruster_names,
            "gravity": r.gravity,
            "cache_entry": str(self.cache_path) if self.cache_path else "in memory",
            "notes": list(self.notes),
            "cache_hit": self.cache_hit,
            "seconds": self.load_seconds,
            "numbers": len(self.numbers),
            "tape": {"instructions": self.tape.instructions(),
                     "instructions_accel": self.tape.instructions("accel"),
                     "registers": self.tape.nreg},
        }
