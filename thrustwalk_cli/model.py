"""Compiled numeric robot models (SPEC section 1). Loading a cached model never imports SymPy.

``load_model(robot)`` returns a :class:`CompiledModel` whose methods evaluate one state
(shape ``(N,)``) or a batch (shape ``(..., N)``) without Python loops over states:

    D(q) q'' + C(q, q') q' + G(q) = B_tau u + B_F(q) F_T        (pinned, SPEC 1)
    h(q, q') = C(q, q') q' + G(q)

Unpinned quantities (``q_u = [q; x_1; y_1]``) do not depend on the foot position, so they
take ``q`` (N) and, where needed, ``dq_u`` (N+2).
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import numpy as np

from . import __version__, cache
from .errors import InputError, Problem
from .robot import Robot


def _generator_digest() -> str:
    """Hash of the derivation and code-generation sources: editing them invalidates caches."""
    h = hashlib.sha256()
    here = Path(__file__).parent
    for name in ("derive.py", "codegen.py"):
        h.update((here / name).read_bytes())
    h.update(repr(sorted(_FUNCTIONS.items())).encode())
    return h.hexdigest()

# name -> (argument list, doc) of every generated function
_FUNCTIONS: dict[str, tuple[tuple[str, ...], str]] = {
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
}

_VECTORS = {"G", "h", "V", "h_u", "p_swing", "p_com", "link_points"}


def model_key(robot: Robot) -> str:
    """Cache key: hash of the robot's content, the tool version and the generator sources."""
    blob = json.dumps(
        {"robot": robot.canonical(), "version": __version__, "codegen": _generator_digest()},
        sort_keys=True,
    )
    return hashlib.sha256(blob.encode()).hexdigest()


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
    """A robot description plus its generated numeric functions.

    The description is immutable; per-run buffers never live here.
    """

    def __init__(self, robot: Robot, module: ModuleType, path: Path, key: str,
                 cache_hit: bool, seconds: float):
        self.robot = robot
        self._m = module
        self.cache_path = path
        self.key = key
        self.cache_hit = cache_hit
        self.load_seconds = seconds
        self.n = robot.n
        self.n_thrusters = len(robot.thrusters)
        self.R = robot.R
        self.b = robot.b
        self.B_tau = np.vstack([np.eye(self.n - 1), np.zeros((1, self.n - 1))])
        for name in _FUNCTIONS:
            setattr(self, name, getattr(module, name))
            setattr(self, name + "_s", getattr(module, name + "_s"))

    # -- derived quantities ----------------------------------------------------------------
    def energy(self, q: np.ndarray, dq: np.ndarray) -> np.ndarray:
        """Mechanical energy ``1/2 q'^T D q' + V`` [J] (pinned)."""
        q, dq = np.asarray(q, float), np.asarray(dq, float)
        K = 0.5 * np.einsum("...i,...ij,...j->...", dq, self.D(q), dq)
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
            "cache_entry": str(self.cache_path),
            "cache_hit": self.cache_hit,
            "seconds": self.load_seconds,
        }


def _problem(robot: Robot, path: str, message: str) -> Problem:
    return Problem(robot.source_file, robot.line_of(path), path, message)


def generate_source(robot: Robot, key: str) -> str:
    """Derive with SymPy and generate the model module's source (imports SymPy lazily)."""
    from . import codegen, derive

    der = derive.derive(robot)
    qN = der.q[-1]
    if qN in der.exprs["D"].free_symbols:
        raise InputError(_problem(
            robot, "coordinates.unactuated",
            "the inertia matrix depends on q_N (dD/dq_N != 0): q_N must be an absolute angle "
            "and q_b relative joint angles, otherwise SPEC 3's zero dynamics do not apply",
        ))
    argsyms = {"q": der.q, "dq": der.dq, "dq_u": der.dq + der.dxy}
    funcs = []
    for name, (args, doc) in _FUNCTIONS.items():
        funcs.append(codegen.generate_function(
            name, der.exprs[name], [(a, argsyms[a]) for a in args], doc,
            vector=name in _VECTORS))
    header = (
        f"Generated by thrustwalk {__version__} for robot {robot.name!r}. Do not edit.\n\n"
        f"Coordinates q (in order): {robot.coordinate_names!r}"
    )
    return codegen.generate_module(header, funcs, {"KEY": key, "N": robot.n})


def load_model(robot: Robot, *, rebuild: bool = False) -> CompiledModel:
    """Load the compiled model from the cache, or compile it (SPEC 1) and cache it.

    A cache entry that is missing, stale, corrupted or partially written is rebuilt.
    Compile-time checks: D symmetric positive definite, dD/dq_N = 0, R invertible and mapping
    the swing foot to the stance foot (``InputError`` naming the file and key otherwise).
    """
    t0 = time.perf_counter()
    key = model_key(robot)
    path = cache.entry_path(robot.name, key)
    memo = _LOADED.get(str(path))
    if not rebuild and memo is not None and memo[0] == _signature(path) and \
            memo[1].key == key and memo[1].robot == robot:
        # already imported in this process and the entry is untouched: no re-import
        m = memo[1]
        return CompiledModel(m.robot, m._m, path, key, True, time.perf_counter() - t0)
    hit = not rebuild and cache.verify_entry(path, key) is None
    if not hit:
        source = generate_source(robot, key)
        cache.write_entry(path, key, source)
        if cache.verify_entry(path, key) is not None:  # pragma: no cover - disk trouble
            raise OSError(f"cache entry {path} could not be written")
    module = cache.import_entry(path, key)
    model = CompiledModel(robot, module, path, key, hit, time.perf_counter() - t0)
    if not hit:
        check_model(model)
    _LOADED[str(path)] = (_signature(path), model)
    return model


# Models imported in this process, by cache entry: (entry mtime and size, model). A rewritten
# or corrupted entry changes its signature and goes through verification again.
_LOADED: dict[str, tuple[tuple[int, int] | None, CompiledModel]] = {}


def _signature(path: Path) -> tuple[int, int] | None:
    try:
        st = path.stat()
    except OSError:
        return None
    return (st.st_mtime_ns, st.st_size)


def check_model(model: CompiledModel, samples: int = 16, seed: int = 0) -> None:
    """Numeric compile-time checks at random configurations (seeded)."""
    robot = model.robot
    rng = np.random.default_rng(seed)
    q = rng.uniform(-1.0, 1.0, size=(samples, model.n))
    D = model.D(q)
    problems = []
    if not np.allclose(D, np.swapaxes(D, -1, -2), rtol=0, atol=1e-12 * max(1.0, np.abs(D).max())):
        problems.append(_problem(robot, "links", "inertia matrix D is not symmetric"))
    elif np.linalg.eigvalsh(D).min() <= 0:
        problems.append(_problem(robot, "links",
                                 "inertia matrix D is not positive definite: check masses and "
                                 "inertias (a link with no mass and no inertia?)"))
    R = model.R
    if abs(np.linalg.det(R)) < 1e-9:
        problems.append(_problem(robot, "relabel", "relabelling matrix R is singular"))
    else:
        p = model.p_swing(q)
        qp = model.relabel(q)
        err_foot = np.abs(model.p_swing(qp) + p).max()
        err_com = np.abs(model.p_com(qp) - (model.p_com(q) - p)).max()
        if err_foot > 1e-9 or err_com > 1e-9:
            problems.append(_problem(
                robot, "relabel",
                f"relabelling does not swap the feet: after q+ = R q + b the swing foot is "
                f"{err_foot:.3g} m and the centre of mass {err_com:.3g} m away from where the "
                f"leg swap puts them (check R, b or the declared symmetry)"))
    if problems:
        model.cache_path.unlink(missing_ok=True)
        raise InputError(problems)
