"""The ``stability`` study: Floquet multipliers of the full-order closed loop with its thruster
states, for one setting or a sweep of one parameter (SPEC 13).

Each case is analysed by :func:`thrustwalk_cli.floquet.multipliers.analyse`: fixed point of the
Poincare map on the impact surface by Newton from the zero-dynamics prediction, Jacobian on a
section of dimension ``n - 1`` by central differences (compiled simulation) and by the
variational equations with saltation, multipliers compared with ``delta_zero^2`` (SPEC 3).
Documents and figure data are plain Python built here. Units: SI; multipliers [1], gains
``K_p`` [1/s^2], ``K_d`` [1/s].
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..errors import (
    InputError,
    check_callable,
    check_flag,
    check_number,
    check_numbers,
    check_text,
)
from ..floquet.multipliers import (
    AGREEMENT_FLOOR,
    AGREEMENT_RULE,
    MARGIN,
    SAFETY,
    Floquet,
    analyse,
    check_agreement_tol,
)
from ..floquet.poincare import Setting
from ..model.slope import check_slope
from ..simulation.closed_loop import (
    SimConfig,
    ThrustModel,
    check_thruster_rate,
)
from ..simulation.full_order import Start
from ..simulation.scenario import make_scenario
from ..thrust.command import given_dynamics
from ..thrust.dynamics import MODELS, ThrusterDynamics, canonical
from ..walker import Walker, check_walker
from .documents import (
    SCHEMA_VERSION,
    Table,
    col,
    dynamics_record,
    gait_record,
    result_repr,
    robot_record,
    slope_record,
    units,
)

UNITS = units("thrust", "time", "q", "q_dot", "wn", "tau", "multiplier", "kp", "kd", "xi",
              "delta_zero_sq", "zeta")

# the parameters `vary` sweeps and their units; wn, xi and tau only with a thrust model that
# takes them (thrust/dynamics.py: MODELS)
VARY = {"kp": "1/s^2", "kd": "1/s", "wn": "rad/s", "xi": "1", "tau": "s", "thrust": "N"}


def model_params(kind: str) -> tuple[str, ...]:
    """The thruster parameters (wn, xi, tau) the thrust model ``kind`` takes."""
    model = MODELS.get(canonical(kind))
    return () if model is None else model.params
MAX_CASES = 200  # settings in one sweep (each takes about 1-3 s)
VERDICTS = ("stable", "unstable", "undetermined", "no orbit")


def _c(z: complex | None) -> dict | None:
    return None if z is None else {"re": float(z.real), "im": float(z.imag)}


def _fmt_c(z: complex) -> str:
    return f"{z.real:.6g}" if z.imag == 0 else f"{z.real:.6g}{z.imag:+.6g}i"


@dataclass(frozen=True)
class Case:
    """One analysed setting: the varied value (None without a sweep) and the analysis."""

    value: float | None
    floquet: Floquet
    thrust: float
    thruster: str | None


def case_entry(i: int, case: Case) -> dict:
    """One entry of ``cases`` in stability.json."""
    f = case.floquet
    s = f.setting
    th = s.thrust
    takes = model_params(th.kind)
    entry = {
        "case": i, "value": case.value, "thrust": case.thrust, "thruster": case.thruster,
        "kp": s.kp, "kd": s.kd, "wn": th.wn if "wn" in takes else None,
        "xi": th.xi if "xi" in takes else None, "tau": th.tau if "tau" in takes else None,
        "exists": f.exists, "verdict": f.verdict, "stable": f.stable, "reason": f.reason,
        "predicted": {"zeta_star": f.predicted_zeta_star,
                      "step_time": f.predicted_step_time},
        "state_names": list(f.names),
        "fixed_point": None, "jacobian": None, "multipliers": [], "spectral_radius": None,
        "zero_dynamics": None, "output_reference": None, "simulations": f.simulations,
    }
    fp = f.fixed_point
    if fp is not None:
        entry["fixed_point"] = {
            "converged": fp.converged,
            "state": dict(zip(f.names, map(float, fp.x))),
            "prediction": dict(zip(f.names, map(float, fp.x0))),
            "distance_from_prediction": float(np.max(np.abs(fp.x - fp.x0))),
            "step_time": None if not np.isfinite(fp.step_time) else fp.step_time,
            "newton": {"iterations": fp.iterations, "residual": _finite(fp.residual),
                       "start_residual": _finite(fp.history[0]) if fp.history else None,
                       "history": [_finite(v) for v in fp.history], "tolerance": fp.tol,
                       "reason": fp.reason or None,
                       "residual_definition": "max |P(x) - x| / max(1, max |x|)"},
        }
    if f.fd is not None and f.variational is not None:
        fd, var = f.fd, f.variational
        entry["jacobian"] = {
            "finite_differences": {
                "ok": fd.ok, "step": fd.step, "error_estimate": _finite(fd.error),
                "steps": [{"step": h, "change_to_next": c} for h, c in fd.steps],
                "reason": fd.reason or None,
                "method": "central differences of the compiled one-step simulation along an "
                          "orthonormal basis of the guard's tangent space; the step is the "
                          "middle of the plateau (least change to both neighbours)"},
            "variational": {
                "ok": var.ok, "reason": var.reason or None, "step_time": var.T if var.ok
                else None, "rhs_jacobians": var.evaluations,
                "trivial_multiplier": _c(var.trivial_multiplier) if var.ok else None,
                "flow_residual": _finite(var.flow_residual) if var.ok else None,
                "method": "Phi' = f_x Phi along the orbit (DOP853), DP = (I - f g_x/(g_x f)) "
                          "Phi_T DDelta; f_x exact along q' and z (f polynomial of degree "
                          "<= 2 there), fourth-order Richardson differences along q"},
            "agreement": None if f.agreement is None else agreement_entry(f),
        }
    if f.multipliers:
        entry["multipliers"] = [{
            "re": m.value.real, "im": m.value.imag, "modulus": m.modulus, "kind": m.kind,
            "dominant": [{"component": n, "weight": w} for n, w in m.dominant],
            "thruster_share": m.thruster_share, "zero_dynamics_alignment": m.alignment,
            "finite_difference": _c(m.finite_difference), "difference": m.difference,
            "fd_error_estimate": m.fd_error, "tolerance": m.tolerance, "agrees": m.agrees}
            for m in f.multipliers]
        entry["spectral_radius"] = f.spectral_radius
        zdm = f.zero_dynamics_multiplier
        entry["zero_dynamics"] = None if zdm is None else {
            "multiplier": _c(zdm), "delta_zero_sq": f.delta_zero_sq,
            "difference": abs(zdm - f.delta_zero_sq)}
        entry["output_reference"] = {
            "value": f.output_reference,
            "formula": "exp(max Re(lambda) T*), lambda the roots of s^2 + kd s + kp"}
    return entry


TOLERANCE_SOURCE = {
    "scaled": "max(1e-6, 10 e_j, E) per multiplier, e_j the finite-difference error "
              "estimate carried to multiplier j (its change between the chosen step and the "
              "neighbouring step), E the finite-difference Jacobian's entry error estimate",
    "floor": "1e-6 for every multiplier: the finite differences gave no error estimate (too "
             "few successful steps)",
    "given": "agreement_tol, given, for every multiplier",
}


def agreement_entry(f: Floquet) -> dict:
    """``jacobian.agreement`` of one case: the verdict's test (multipliers against their
    tolerances, the rule and where the tolerance came from) and the entry-wise Jacobian
    difference, reported beside it."""
    worst = max(f.multipliers, key=lambda m: m.difference / m.tolerance)
    j = f.multipliers.index(worst)
    fd_err = _finite(f.fd.error) if f.fd is not None else None
    entries = (f"Jacobian entries differ by {f.agreement:.2g} (relative to max(1, max |J|)"
               + (f"; the finite-difference entries' error estimate is {fd_err:.2g}"
                  if fd_err is not None else "") + "; reported, not judged)")
    return {
        "judged_on": "multipliers",
        "multipliers": f.multiplier_agreement,
        "tolerance": worst.tolerance,
        "tolerance_source": f.tolerance_source,
        "tolerance_rule": TOLERANCE_SOURCE[f.tolerance_source],
        "agreement_tol": f.agreement_tol,
        "worst": {"index": j, "kind": worst.kind, "difference": worst.difference,
                  "tolerance": worst.tolerance, "fd_error_estimate": worst.fd_error},
        "agree": f.agree,
        "jacobian": f.agreement,
        "jacobian_fd_error_estimate": fd_err,
        "radius_error": f.radius_error,
        "statement": (f"finite differences and variational equations "
                      f"{'agree' if f.agree else 'DISAGREE'} on the multipliers: largest "
                      f"difference {f.multiplier_agreement:.2g}; closest to its tolerance: "
                      f"multiplier {j} ({worst.kind}), {worst.difference:.2g} apart against "
                      f"{worst.tolerance:.2g} ({f.tolerance_source}); {entries}; spectral "
                      f"radius error bar {f.radius_error:.2g}"),
    }


def _finite(v: float) -> float | None:
    return float(v) if v is not None and np.isfinite(v) else None


def overall_verdict(cases: Sequence[Case]) -> str:
    """``stable`` only when every case is stable; ``unstable`` when every case is determined
    and some is unstable; ``undetermined`` otherwise (some case undetermined or without an
    orbit)."""
    vs = [c.floquet.verdict for c in cases]
    if all(v == "stable" for v in vs):
        return "stable"
    if all(v in ("stable", "unstable") for v in vs):
        return "unstable"
    return "undetermined"


@dataclass(frozen=True)
class StabilityResult:
    """Floquet analysis of the full-order closed loop for one setting or a sweep (SPEC 13).

    ``success``: every case has a determined verdict (fixed point converged, Jacobians
    agreeing); ``verdict``: see :func:`overall_verdict`; ``reason`` names the cases that are
    not stable and why."""

    __repr__ = result_repr

    walker: Walker = field(repr=False)
    cases: tuple[Case, ...]
    thrust_model: str
    vary: tuple[str, tuple[float, ...]] | None
    settings: dict

    name = "stability"

    @property
    def success(self) -> bool:
        """Every case has a verdict, ``stable`` or ``unstable`` (SPEC 13)."""
        return all(c.floquet.verdict in ("stable", "unstable") for c in self.cases)

    @property
    def verdict(self) -> str:
        """``stable`` (every case), ``unstable`` (every case decided, some unstable) or
        ``undetermined``."""
        return overall_verdict(self.cases)

    @property
    def reason(self) -> str:
        """Each case that is not stable and why, or that every case is stable."""
        bad = [(i, c) for i, c in enumerate(self.cases) if c.floquet.verdict != "stable"]
        if not bad:
            return (f"every case is stable ({len(self.cases)} case"
                    f"{'s' if len(self.cases) > 1 else ''})")
        return "; ".join(f"{self._label(i, c)}: {c.floquet.verdict}: {c.floquet.reason}"
                         for i, c in bad)

    def _label(self, i: int, c: Case) -> str:
        if self.vary is None:
            return "case 0"
        return f"case {i} ({self.vary[0]} = {c.value:g} {VARY[self.vary[0]]})"

    @property
    def warnings(self) -> list[str]:
        """One line per case that is not determined (Newton, disagreement, no orbit) and the
        gait's own warnings."""
        out = list(self.walker.warnings)
        for i, c in enumerate(self.cases):
            if c.floquet.verdict in ("undetermined", "no orbit"):
                out.append(f"{self._label(i, c)}: {c.floquet.verdict}: {c.floquet.reason}")
        return out

    def document(self) -> dict:
        """The JSON body of ``stability.json``."""
        zd = self.walker.zd
        counts = {v: sum(c.floquet.verdict == v for c in self.cases) for v in VERDICTS}
        return {
            "schema_version": SCHEMA_VERSION,
            "units": {**UNITS, "slope": "rad"} if zd.slope != 0.0 else UNITS,
            **({"slope": slope_record(zd.slope)} if zd.slope != 0.0 else {}),
            "success": self.success,
            "verdict": self.verdict,
            "verdicts": counts,
            "reason": self.reason,
            "warnings": self.warnings,
            "robot": robot_record(zd),
            "gait": gait_record(zd),
            "zero_dynamics": {"delta_zero": zd.delta_zero, "delta_zero_sq": zd.delta_zero_sq,
                              "note": "the zero-dynamics Poincare eigenvalue (SPEC 3); "
                                      "with exact output zeroing and a hybrid-invariant gait "
                                      "it is one of the full-order multipliers (SPEC 13)"},
            "settings": {**self.settings,
                         "vary": None if self.vary is None else {
                             "parameter": self.vary[0], "unit": VARY[self.vary[0]],
                             "values": list(self.vary[1])},
                         "section": "the guard's tangent space at the fixed point: x = x* + "
                                    "B xi, B = diag(B_q, I, I) orthonormal with g_q B_q = 0; "
                                    "n - 1 = 2N - 1 + n_z multipliers (the trivial one, 0 for "
                                    "the Poincare map, normal to the guard, is dropped)",
                         "agreement": {
                             "judged_on": "multipliers", "rule": AGREEMENT_RULE,
                             "floor": AGREEMENT_FLOOR, "safety_factor": SAFETY,
                             "agreement_tol": self.settings.get("agreement_tol")},
                         "marginal_band": MARGIN,
                         "reported_multipliers": "eigenvalues of the variational Jacobian; "
                                                 "finite_difference: the matching eigenvalue "
                                                 "of the finite-difference Jacobian"},
            "cases": [case_entry(i, c) for i, c in enumerate(self.cases)],
        }

    def tables(self) -> dict[str, Table]:
        """``multipliers``: one row per multiplier per case."""
        header = ["case", col("value", VARY[self.vary[0]]) if self.vary else "value",
                  "verdict", "index", "re", "im", "modulus", "kind", "thruster_share",
                  "fd_re", "fd_im", "dominant", col("spectral_radius", "1")]
        rows = []
        for i, c in enumerate(self.cases):
            f = c.floquet
            if not f.multipliers:
                rows.append([i, c.value, f.verdict] + [None] * 9 + [None])
                continue
            for j, m in enumerate(f.multipliers):
                rows.append([i, c.value, f.verdict, j, m.value.real, m.value.imag, m.modulus,
                             m.kind, m.thruster_share, m.finite_difference.real,
                             m.finite_difference.imag,
                             " ".join(f"{n}:{w:.3f}" for n, w in m.dominant),
                             f.spectral_radius])
        return {"multipliers": Table(header, rows, [
            "thrustwalk stability: Floquet multipliers of the full-order closed loop [1], "
            "sorted by modulus per case",
            "kind: zero dynamics | outputs | thruster; dominant: largest eigenvector components "
            "(unit eigenvector); fd_*: the finite-difference Jacobian's matching multiplier"])}

    def figure_data(self) -> dict:
        """Plain data for the figures: per case the multipliers (re, im, kind) and the varied
        value; ``delta_zero_sq``; the varied parameter's label."""
        cases = []
        for c in self.cases:
            f = c.floquet
            cases.append({"value": c.value, "verdict": f.verdict,
                          "re": np.array([m.value.real for m in f.multipliers]),
                          "im": np.array([m.value.imag for m in f.multipliers]),
                          "kind": [m.kind for m in f.multipliers],
                          "spectral_radius": f.spectral_radius})
        label = None
        if self.vary is not None:
            name, unit = self.vary[0], VARY[self.vary[0]]
            label = f"{PARAM_LABEL[name]} [{unit}]"
        return {"cases": cases, "delta_zero_sq": self.walker.zd.delta_zero_sq,
                "label": label}

    def figures(self, titles: bool = False) -> dict:
        """``multipliers`` (complex plane with the unit circle) and, with a sweep,
        ``spectral_radius`` (modulus of each multiplier against the varied parameter)."""
        from ..plots.stability import multiplier_plane, spectral_radius

        data = self.figure_data()
        name = self.walker.name
        out = {"multipliers": multiplier_plane(
            data, title=f"{name}: Floquet multipliers" if titles else "")}
        if self.vary is not None:
            out["spectral_radius"] = spectral_radius(
                data, title=f"{name}: multipliers vs {self.vary[0]}" if titles else "")
        return out


PARAM_LABEL = {"kp": "$K_p$", "kd": "$K_d$", "wn": r"$\omega_n$", "xi": r"$\xi$",
               "tau": r"$\tau$", "thrust": "$F_{ss}$"}


def _check_vary(vary, kind: str, wn: float, xi: float, tau: float
                ) -> tuple[str, tuple[float, ...]] | None:
    if vary is None:
        return None
    if isinstance(vary, (str, bytes)) or not isinstance(vary, (tuple, list)) or \
            len(vary) != 2 or not isinstance(vary[0], str):
        raise InputError.param("vary", "must be a pair (name, values), e.g. (\"wn\", [1.0, "
                                       f"2.0]); got {type(vary).__name__} {vary!r:.40}")
    name = vary[0]
    values = check_numbers("vary", vary[1], min_len=0)
    if name not in VARY:
        raise InputError.param("vary", f"unknown parameter {name!r} (choose from "
                                       f"{', '.join(VARY)})")
    if name in ("wn", "xi", "tau") and name not in model_params(kind):
        need = " or ".join(k for k, m in MODELS.items() if name in m.params)
        raise InputError.param("vary", f"{name} is a parameter of the {need} thrust model "
                                       f"(`thrust_model` is {kind})")
    if name == "thrust" and kind == "piecewise":
        raise InputError.param("vary", "the piecewise thrust model takes its thrust from the "
                                       "gait's thrust: section; vary another parameter")
    if not values:
        raise InputError.param("vary", "no values")
    if len(values) > MAX_CASES:
        raise InputError.param("vary", f"{len(values)} values: the limit is {MAX_CASES} (each "
                                       f"takes a few seconds)")
    if not all(np.isfinite(values)):
        raise InputError.param("vary", "values must be finite")
    if name != "thrust" and not all(v > 0 for v in values):
        raise InputError.param("vary", f"{name} must be > 0 (got "
                                       f"{min(values):g})")
    if name in ("wn", "xi", "tau"):
        for v in values:
            try:
                check_thruster_rate(kind, **{"wn": wn, "xi": xi, "tau": tau, name: v})
            except InputError as exc:
                raise InputError.param("vary", f"{name} = {v:g}: "
                                               f"{exc.problems[0].message}") from None
    return name, values


def stability(walker: Walker, *, thrust_model: str | ThrusterDynamics | None = None,
              thrust: float | None = None,
              thruster: str | None = None, wn: float = 2.0, xi: float = 1.0, tau: float = 0.5,
              kp: float | None = None, kd: float | None = None,
              vary: tuple[str, Sequence[float]] | None = None, rtol: float = 1e-12,
              atol: float = 1e-12, agreement_tol: float | None = None,
              progress: Callable[[int], None] | None = None, check_only: bool = False,
              slope: float = 0.0) -> StabilityResult | None:
    """Floquet multipliers of the full-order closed loop (SPEC 13) at steady thrust ``thrust``
    [N] (default 0) on ``thruster`` (default: the first), thrust model ``thrust_model``
    (``ideal``, ``first-order`` with ``tau`` [s], ``second-order`` with ``wn`` [rad/s] and
    ``xi`` [1], ``piecewise``: the gait's ``thrust:`` section, or a
    :class:`~thrustwalk_cli.thrust.dynamics.ThrusterDynamics` built once, e.g. by
    ``tw.thruster_dynamics``, whose own parameters then hold; default as ``simulate``:
    piecewise for a gait with a schedule and no ``thrust``, else second-order), output gains
    ``kp`` [1/s^2], ``kd`` [1/s] (default: the gait's). ``vary``: ``(name, values)`` sweeps one
    of ``kp``, ``kd``, ``wn``, ``xi``, ``tau``, ``thrust`` (one case per value). ``rtol``,
    ``atol``: tolerances of the compiled simulation (the finite differences need about 1e-12).
    ``agreement_tol`` [1]: the largest accepted difference between the multipliers of the two
    methods (finite, > 0; default None: ``max(1e-6, 10 e_j, E)`` per multiplier, ``e_j`` the
    finite-difference error estimate carried to it, ``E`` the entries'; see
    :mod:`thrustwalk_cli.floquet.multipliers`). ``progress(1)`` after each case. Bad
    parameters raise :class:`InputError` naming them. ``check_only``: check every argument,
    compute nothing and return None. ``slope`` [rad, positive uphill, |slope| < pi/2]: the
    ground angle (SPEC 14, :meth:`Walker.on_slope`): the orbit, the compiled simulation of the
    finite differences and the variational equations are those of the slope frame (the
    zero-dynamics multiplier delta_zero^2 does not depend on it); 0: level ground, bit for
    bit."""
    check_walker(walker)
    walker = walker.on_slope(check_slope(slope))
    thrust = check_number("thrust", thrust, optional=True, unit="N")
    check_text("thruster", thruster, optional=True)
    wn = check_number("wn", wn, gt=0, unit="rad/s")
    xi = check_number("xi", xi, gt=0)
    tau = check_number("tau", tau, gt=0, unit="s")
    kp = check_number("kp", kp, gt=0, optional=True, unit="1/s^2")
    kd = check_number("kd", kd, gt=0, optional=True, unit="1/s")
    rtol = check_number("rtol", rtol, gt=0, lt=0.1)
    atol = check_number("atol", atol, gt=0, lt=0.1)
    check_agreement_tol(agreement_tol)
    check_callable("progress", progress)
    zd = walker.zd
    robot = walker.robot
    if thrust_model is None:
        thrust_model = ("piecewise" if walker.gait.thrust is not None and thrust is None
                        else "second-order")
    dynamics = given_dynamics(thrust_model, zd.model.n_thrusters)  # a model given as an object
    # the deprecated `constant` is `ideal`; a model given as an object is named by its kind
    thrust_model = dynamics.kind if dynamics is not None else canonical(thrust_model)
    vary_t = _check_vary(vary, thrust_model, wn, xi, tau)
    kp = float(walker.gait.kp if kp is None else kp)
    kd = float(walker.gait.kd if kd is None else kd)
    schedule = None
    if thrust_model == "piecewise":
        if walker.gait.thrust is not None and thrust is not None:
            raise InputError.param("thrust", "not used with the piecewise thrust model (the "
                                             "schedule comes from the gait's thrust: section)")
        schedule = walker.gait_schedule()
    base = 0.0 if thrust is None else float(thrust)
    values = [base] + (list(vary_t[1]) if vary_t and vary_t[0] == "thrust" else [])
    config = SimConfig(steps=1, rtol=rtol, atol=atol)
    sc = make_scenario(zd, dynamics or thrust_model,
                       None if thrust_model == "piecewise" else values,
                       [thruster] if thruster else None, schedule=schedule, wn=wn, xi=xi,
                       tau=tau, f0=0.0, start=Start(), config=config)
    for key, v in (("kp", kp), ("kd", kd)):
        if not v > 0:
            raise InputError.param(key, f"must be > 0 (got {v:g})")
    if check_flag("check_only", check_only):
        return None
    m = zd.model.n_thrusters
    driven = robot.thruster_names[sc.thrusters[0]] if sc.thrusters else None

    def setting(**over) -> tuple[Setting, float]:
        p = {"thrust": base, "kp": kp, "kd": kd, "wn": wn, "xi": xi, "tau": tau, **over}
        target = np.zeros(m)
        if sc.thrusters:
            target[sc.thrusters[0]] = p["thrust"]
        th = ThrustModel(thrust_model, target, wn=p["wn"], xi=p["xi"], tau=p["tau"],
                         schedule=schedule, dynamics=dynamics)
        return Setting(th, p["kp"], p["kd"], rtol, atol), p["thrust"]

    todo = ([(None, {})] if vary_t is None else
            [(v, {vary_t[0]: v}) for v in vary_t[1]])
    cases = []
    for value, over in todo:
        s, F = setting(**over)
        cases.append(Case(value, analyse(zd, s, agreement_tol=agreement_tol),
                          F if thrust_model != "piecewise" else 0.0, driven))
        if progress is not None:
            progress(1)
    settings = {"thrust_model": thrust_model, "thruster": driven,
                "thrust": None if thrust_model == "piecewise" else base, "kp": kp, "kd": kd,
                "wn": wn if "wn" in model_params(thrust_model) else None,
                "xi": xi if "xi" in model_params(thrust_model) else None,
                "tau": tau if "tau" in model_params(thrust_model) else None,
                "rtol": rtol, "atol": atol,
                "agreement_tol": None if agreement_tol is None else float(agreement_tol),
                **({"thruster_dynamics": dynamics_record(dynamics)} if dynamics is not None
                   else {})}
    return StabilityResult(walker, tuple(cases), thrust_model, vary_t, settings)
