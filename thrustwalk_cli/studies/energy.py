"""The ``energy`` study: what walking with thrust costs, on the zero-dynamics orbits of a gait
over constant thrust values, and, with a gait library, at each speed the cheapest way there
(SPEC 15).

For every constant thrust ``F`` [N] on one thruster: the periodic orbit (SPEC 3, 4) with its
verdict (the ``limit-cycle`` study's: orbit, stability, swing foot, contact at the gait's
``mu``) and, for a stable orbit, its step energies by exact quadrature on Z
(:func:`~thrustwalk_cli.energetics.orbit.orbit_energy`): speed [m/s], step time [s], step
length [m], the joints' net, positive and absolute work [J], their electrical energy (motor
models), the thrust's work on the walker and the thrusters' input energy (power models), the
impact loss ``K^- - K^+`` [J], the costs of transport ``E / (m g d)`` (mechanical: joints'
positive work + thrusters' positive work; total: joints' electrical + thrusters' input; each
split legs / thrust) and the average powers [W]. A missing model leaves its numbers None with
the reason; an orbit that does not exist or is unstable has no energies (None, with why).

With a gait library (the folder of a ``design-gait`` sweep over ``target_speed``): every
library gait designed without thrust, at zero thrust, is a point (speed, CoT) of the strategy
*a gait designed for that speed*; the command's gait over the thrust values is the strategy
*the gait pushed by thrust*. Both curves are compared at common speeds by linear
interpolation in speed (the Pareto table): the cheaper one at each speed, where each is
available, and where the speed ranges do not overlap. The CoT compared is the total one
when every point has it, else the mechanical one (said).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..energetics.orbit import OrbitEnergy, power_profile
from ..errors import InputError, check_number, check_numbers, check_path, check_text
from ..hzd.zero_dynamics import LimitCycle
from ..walker import Walker, check_walker, gait_on_robot
from .documents import (
    SCHEMA_VERSION,
    Table,
    col,
    gait_record,
    result_repr,
    robot_record,
    slope_record,
    units,
)
from .limit_cycle import DEFAULT_THRUST, LimitCycleResult, limit_cycle

PROFILE_SAMPLES = 201  # points along the step of the power figure
COT_KEYS = ("mechanical", "mechanical_legs", "mechanical_thrust", "total", "total_legs",
            "total_thrust")
POWER_KEYS = ("legs_mechanical", "thrust_mechanical", "legs_electrical", "thrust_input")
DESIGNED = "designed gait"
PUSHED = "gait + thrust"
STRATEGY_TEXT = {DESIGNED: "a library gait designed for the speed, without thrust",
                 PUSHED: "the command's gait pushed by constant thrust"}


def _finite(v) -> float | None:
    """A number for a document or a table: None for a missing or non-finite one."""
    if v is None:
        return None
    v = float(v)
    return v if np.isfinite(v) else None


def _word(lc: LimitCycle, verdict: str, walkable: bool) -> str:
    """A case's verdict in a word (the limit-cycle table's words)."""
    if walkable:
        return "walkable"
    if not lc.exists:
        return "no orbit"
    if not lc.stable:
        return "unstable"
    if "swing foot" in verdict or "scuff" in verdict:
        return "scuffs"
    if "vertical ground force" in verdict:
        return "lifts"
    if "friction ratio" in verdict:
        return "slips"
    if "impact" in verdict or "lift" in verdict:
        return "impact"
    return "infeasible"


@dataclass(frozen=True)
class Case:
    """One orbit of the comparison: a thrust value of the command's gait or a library gait
    at zero thrust. ``energy`` None (with ``energy_reason``) without a stable orbit."""

    label: str  # "-20 N" or the library gait's name
    thrust: float | None
    cycle: LimitCycle
    verdict: str  # the limit-cycle verdict, in words
    walkable: bool
    energy: OrbitEnergy | None
    energy_reason: str
    file: str | None = None  # a library gait's file
    target_speed: float | None = None  # [m/s] a library gait's design target

    @property
    def word(self) -> str:
        """The case's verdict in a word: walkable, no orbit, unstable, scuffs, lifts, slips,
        impact or infeasible."""
        return _word(self.cycle, self.verdict, self.walkable)

    def cot(self) -> dict:
        """Costs of transport [1] (SPEC 15), mechanical and total, legs and thrust; all None
        without energies."""
        return self.energy.cot() if self.energy is not None else dict.fromkeys(COT_KEYS)

    def power(self) -> dict:
        """Average power per part [W] (SPEC 15); all None without energies."""
        if self.energy is None:
            return dict.fromkeys(POWER_KEYS)
        return self.energy.record()["average_power"]

    def speed(self) -> float | None:
        """The orbit's walking speed [m/s]; None without an orbit."""
        return _finite(self.cycle.speed) if self.cycle.exists else None

    def record(self) -> dict:
        """The case's JSON entry (SI units)."""
        lc = self.cycle
        e = self.energy
        return {
            "thrust": self.thrust,
            **({"gait": self.label, "file": self.file, "target_speed": self.target_speed}
               if self.file is not None else {}),
            "verdict": self.word, "walkable": self.walkable, "reason": self.verdict,
            "exists": lc.exists, "stable": lc.stable,
            "speed": self.speed(),
            "step_time": _finite(lc.step_time) if lc.exists else None,
            "step_length": _finite(lc.step_length) if lc.exists else None,
            "zeta_star": _finite(lc.zeta_star),
            "energy": None if e is None else e.record(),
            "energy_reason": self.energy_reason,
        }

    def row(self) -> list:
        """The case's numbers for a CSV row (empty = missing; see :data:`ROW_HEADER`)."""
        lc, e = self.cycle, self.energy
        speed = self.speed()
        base = [self.word, self.walkable, speed,
                _finite(lc.step_time) if lc.exists else None,
                _finite(lc.step_length) if lc.exists else None]
        if e is None:
            return base + [None] * (len(ROW_HEADER) - len(base) - 1) + [self.energy_reason]
        sums = [sum(e.joint_work), sum(e.joint_positive_work), sum(e.joint_absolute_work),
                e.legs_electrical, sum(e.thrust_work), sum(e.thrust_positive_work),
                e.thrust_input, e.impact_loss]
        cot, pw = self.cot(), self.power()
        return (base + [_finite(v) for v in sums] + [_finite(cot[k]) for k in COT_KEYS]
                + [_finite(pw[k]) for k in POWER_KEYS] + [self.energy_reason])


ROW_HEADER = (["verdict", "walkable", col("speed", "m/s"), col("step_time", "s"),
               col("step_length", "m"), col("joint_net_work", "J"),
               col("joint_positive_work", "J"), col("joint_absolute_work", "J"),
               col("joint_electrical", "J"), col("thrust_work", "J"),
               col("thrust_positive_work", "J"), col("thruster_input", "J"),
               col("impact_loss", "J")]
              + [f"cot_{k}" for k in COT_KEYS] + [col(f"power_{k}", "W") for k in POWER_KEYS]
              + ["reason"])


def _cases(sweep: LimitCycleResult, labels: Sequence[str], **extra) -> list[Case]:
    """The cases of a limit-cycle result: energies only for stable orbits."""
    out = []
    energies = sweep.energy or (None,) * len(sweep.cycles)
    for i, (lc, verdict, ok, e) in enumerate(zip(sweep.cycles, sweep.verdicts, sweep.walkable,
                                                 energies)):
        if not lc.exists:
            why = lc.missing + ": no energies"
            e = None
        elif not lc.stable:
            why = (f"the periodic orbit is unstable (delta_zero^2 = "
                   f"{sweep.walker.zd.delta_zero_sq:.4g} >= 1): the walker does not settle on "
                   "it; no energies")
            e = None
        else:
            why = "energies of the periodic orbit's step (exact quadrature on Z)"
            if not ok:
                why += "; the orbit is not walkable (see verdict): its energies are not a gait's"
        out.append(Case(labels[i], sweep.thrust[i], lc, verdict, ok, e, why,
                        **{k: v[i] for k, v in extra.items()}))
    return out


def _basis(cases: Sequence[Case]) -> str:
    """``total`` when every case with energies has a total CoT, else ``mechanical``."""
    live = [c for c in cases if c.energy is not None]
    return "total" if live and all(c.cot()["total"] is not None for c in live) else "mechanical"


def _curve(cases: Sequence[Case], basis: str) -> tuple[np.ndarray, np.ndarray, list[Case]]:
    """(speeds, CoTs) of the walkable cases with energies, sorted by speed."""
    live = [c for c in cases if c.walkable and c.energy is not None
            and c.cot()[basis] is not None and c.speed() is not None]
    live.sort(key=lambda c: c.speed())
    return (np.array([c.speed() for c in live], float),
            np.array([c.cot()[basis] for c in live], float), live)


def _interp(v: float, xs: np.ndarray, ys: np.ndarray) -> float | None:
    """The curve (xs, ys) at ``v`` by linear interpolation; None outside its range."""
    if xs.size == 0 or v < xs[0] or v > xs[-1]:
        return None
    return float(np.interp(v, xs, ys))


def pareto_rows(designed: Sequence[Case], pushed: Sequence[Case], basis: str) -> list[dict]:
    """At every speed of either curve (walkable orbits only): each strategy's CoT (``basis``)
    interpolated linearly in speed where the speed is inside its range, and the cheapest."""
    xa, ya, _ = _curve(designed, basis)
    xb, yb, _ = _curve(pushed, basis)
    rows = []
    speeds = np.unique(np.concatenate([xa, xb]))
    if speeds.size:  # one row for speeds equal to rounding (a design hits its target)
        speeds = speeds[np.concatenate([[True], np.diff(speeds) > 1e-9 * speeds[1:]])]
    for v in speeds:
        a, b = _interp(v, xa, ya), _interp(v, xb, yb)
        if a is None and b is None:
            continue
        if a is not None and b is not None:
            cheapest = DESIGNED if a < b else PUSHED if b < a else "tie"
        else:
            cheapest = DESIGNED if b is None else PUSHED
        rows.append({"speed": float(v), DESIGNED: a, PUSHED: b, "cheapest": cheapest,
                     "compared": a is not None and b is not None})
    return rows


def pareto_headline(rows: Sequence[dict], designed: Sequence[Case], pushed: Sequence[Case],
                    basis: str, gait: str) -> str:
    """Where thrust pays and where it does not, from the Pareto rows (computed)."""
    xa, _, _ = _curve(designed, basis)
    xb, _, _ = _curve(pushed, basis)

    def rng(x: np.ndarray) -> str:
        return f"{x[0]:.3g} m/s" if x[0] == x[-1] else f"{x[0]:.3g}-{x[-1]:.3g} m/s"

    if not xa.size or not xb.size:
        which = "the library's gaits" if not xa.size else f"{gait} with thrust"
        return f"no comparison: {which} have no walkable orbit with a {basis} CoT"
    both = [r for r in rows if r["compared"]]
    if not both:
        return (f"no common speed: the designed gaits walk at {rng(xa)}, {gait} with thrust "
                f"at {rng(xb)} (the ranges do not overlap)")
    parts = []
    runs: list[list[dict]] = []  # consecutive speeds with the same answer
    for r in rows:
        if runs and (runs[-1][-1]["cheapest"], runs[-1][-1]["compared"]) == \
                (r["cheapest"], r["compared"]):
            runs[-1].append(r)
        else:
            runs.append([r])
    for run in runs:
        lo, hi = run[0]["speed"], run[-1]["speed"]
        span = f"at {lo:.3g} m/s" if lo == hi else f"from {lo:.3g} to {hi:.3g} m/s"
        if not run[0]["compared"]:
            who = f"{gait} with thrust" if run[0]["cheapest"] == PUSHED else "the designed gaits"
            parts.append(f"only {who} {'reach' if who.endswith('s') else 'reaches'} "
                         + (f"{lo:.3g} m/s" if lo == hi else f"{lo:.3g}-{hi:.3g} m/s"))
            continue
        def span3(vals: list[float]) -> str:
            lo_, hi_ = f"{min(vals):.3g}", f"{max(vals):.3g}"
            return lo_ if lo_ == hi_ else f"{lo_}-{hi_}"

        nums = (f"{basis} CoT {span3([r[PUSHED] for r in run])} with thrust vs "
                f"{span3([r[DESIGNED] for r in run])} designed")
        if run[0]["cheapest"] == PUSHED:
            parts.append(f"thrust pays {span} ({nums})")
        elif run[0]["cheapest"] == DESIGNED:
            parts.append(f"a gait designed for the speed is cheaper {span} ({nums})")
        else:
            parts.append(f"the two cost the same {span}")
    if not any(r["cheapest"] == PUSHED for r in both):
        parts.append("thrust pays nowhere in the common range")
    return "; ".join(parts)


@dataclass(frozen=True)
class EnergyResult:
    """The energy of one gait over constant thrust values (``cases``, one per thrust value
    [N]) and, with a gait library, of the library's gaits at zero thrust (``library``) with
    the Pareto comparison (module docstring; SI units). ``profiles``: the power along the
    step (:func:`~thrustwalk_cli.energetics.orbit.power_profile`) of the nominal case (thrust
    0, or the value nearest it with energies) and the extreme one (the farthest from it).
    ``success``: at least one thrust value has a stable orbit with energies (a sweep without
    any is an answer, said in ``reason``)."""

    __repr__ = result_repr

    walker: Walker = field(repr=False)
    sweep: LimitCycleResult = field(repr=False)
    cases: tuple[Case, ...] = field(repr=False)
    profiles: dict = field(default_factory=dict, repr=False)
    library: tuple[Case, ...] | None = field(default=None, repr=False)
    library_folder: str | None = None
    skipped: tuple[str, ...] = ()

    name = "energy"

    # -- verdicts ---------------------------------------------------------------------------
    @property
    def thruster_name(self) -> str | None:
        """The thruster the constant thrust drives (None: the robot has none)."""
        return self.sweep.thruster_name

    @property
    def basis(self) -> str:
        """The CoT compared: ``total`` when every case with energies (and every library gait)
        has it, else ``mechanical``."""
        return _basis(list(self.cases) + list(self.library or ()))

    @property
    def missing(self) -> list[str]:
        """The models the robot file does not give (one line each), from the cases."""
        seen: list[str] = []
        for c in list(self.cases) + list(self.library or ()):
            for m in (c.energy.missing if c.energy is not None else ()):
                if m not in seen:
                    seen.append(m)
        return seen

    @property
    def success(self) -> bool:
        """Some thrust value has energies (a stable periodic orbit)."""
        return any(c.energy is not None for c in self.cases)

    @property
    def reason(self) -> str:
        """How many thrust values have energies and how many are walkable, and the headline."""
        n = sum(c.energy is not None for c in self.cases)
        if not n:
            return "no thrust value has a stable periodic orbit: no energies"
        w = sum(c.walkable for c in self.cases)
        return (f"energies for {n} of {len(self.cases)} thrust values ({w} walkable); "
                f"{self.headline}")

    def nominal_extreme(self) -> tuple[int | None, int | None]:
        """Indices of the nominal case (thrust 0, else the value nearest 0, with energies)
        and the extreme one (the thrust farthest from it with energies), among the walkable
        cases (the stable ones when none is walkable: then the headline says so)."""
        live = [i for i, c in enumerate(self.cases) if c.energy is not None]
        live = [i for i in live if self.cases[i].walkable] or live
        if not live:
            return None, None
        th = [abs(self.cases[i].thrust or 0.0) for i in live]
        nom = live[int(np.argmin(th))]
        f0 = self.cases[nom].thrust or 0.0
        ext = max(live, key=lambda i: abs((self.cases[i].thrust or 0.0) - f0))
        return nom, ext

    @property
    def headline(self) -> str:
        """E.g. "thrust -20 N raises speed from 0.61 to 0.74 m/s at total CoT 0.9 -> 2.3: the
        thruster input dominates (legs 0.4, thrust 1.9)": the nominal and extreme cases,
        computed."""
        nom, ext = self.nominal_extreme()
        if nom is None:
            return "no stable periodic orbit in the sweep: no energies"
        basis = self.basis
        a, b = self.cases[nom], self.cases[ext]
        ca, cb = a.cot(), b.cot()
        tail = ""
        if basis == "mechanical" and self.missing:
            tail = f"; total CoT not computed ({len(self.missing)} model(s) missing, see missing)"
        if not a.walkable:  # no walkable case: the stable orbits, said to be no gaits
            tail += "; no thrust value is walkable (see the verdicts): these orbits are no gaits"
        f0 = a.thrust or 0.0
        if nom == ext:
            return (f"only thrust {f0:g} N has a stable orbit: {a.speed():.3g} m/s at {basis} "
                    f"CoT {ca[basis]:.3g} (legs {ca[basis + '_legs']:.3g}, thrust "
                    f"{ca[basis + '_thrust']:.3g}){tail}")
        va, vb = a.speed(), b.speed()
        verb = "raises" if vb > va else "lowers" if vb < va else "keeps"
        legs, thr = cb[basis + "_legs"], cb[basis + "_thrust"]
        what = "the thruster input" if basis == "total" else "the thrust's work"
        dom = (f"{what} dominates" if thr > legs else "the legs still dominate")
        start = "" if f0 == 0.0 else f" (from {f0:g} N, the value nearest 0 with an orbit)"
        if a.walkable:  # the extreme is the farthest walkable thrust
            start += " (the farthest walkable value)" if any(
                c.energy is not None and not c.walkable for c in self.cases) else ""
        return (f"thrust {b.thrust:g} N{start} {verb} speed from {va:.3g} to {vb:.3g} m/s at "
                f"{basis} CoT {ca[basis]:.3g} -> {cb[basis]:.3g}: {dom} (legs {legs:.3g}, "
                f"thrust {thr:.3g}){tail}")

    # -- the library comparison -------------------------------------------------------------
    def pareto(self) -> list[dict]:
        """The Pareto rows (:func:`pareto_rows`); empty without a library."""
        if self.library is None:
            return []
        return pareto_rows(self.library, self.cases, self.basis)

    @property
    def library_headline(self) -> str | None:
        """The gait library's Pareto headline (the cheapest way to each speed); None without a
        library."""
        if self.library is None:
            return None
        return pareto_headline(self.pareto(), self.library, self.cases, self.basis,
                               self.walker.gait.name)

    # -- rendering --------------------------------------------------------------------------
    def document(self) -> dict:
        """The JSON body of ``energy.json`` (SI units, see ``units``)."""
        zd = self.walker.zd
        nom, ext = self.nominal_extreme()
        basis = self.basis
        doc = {
            "schema_version": SCHEMA_VERSION,
            "units": units("thrust", "speed", "step_time", "step_length", "zeta", "energy",
                           cot="1", power="W", fuel_mass="kg", fuel_per_metre="kg/m",
                           weight="N"),
            "robot": robot_record(zd),
            "gait": gait_record(zd),
            **({"slope": slope_record(zd.slope)} if zd.slope != 0.0 else {}),
            "thruster": self.thruster_name,
            "success": self.success,
            "reason": self.reason,
            "headline": self.headline,
            "warnings": list(self.walker.warnings) + self.sweep.warnings(),
            "energy": {
                "method": "on each stable orbit by quadrature in alpha (SPEC 15, exact: no "
                          "simulation); kinks of max(0, .) and |.| located",
                "cot": "E / (m g d), d the step length; mechanical: joints' positive work + "
                       "thrusters' positive work on the walker; total: joints' electrical "
                       "energy (motor models) + thrusters' input energy (power models)",
                "weight": self.walker.robot.weight,
                "basis": basis,
                "basis_reason": ("every case has a total CoT" if basis == "total" else
                                 "the total CoT is missing for some case: "
                                 + (self.missing[0] if self.missing else "no stable orbit")),
                "missing": self.missing,
            },
            "contact": {"mu": self.sweep.mu,
                        "checks": "the limit-cycle verdict on each orbit (SPEC 5)"},
            "nominal_thrust": None if nom is None else self.cases[nom].thrust,
            "extreme_thrust": None if ext is None else self.cases[ext].thrust,
            "cases": [c.record() for c in self.cases],
        }
        if self.library is not None:
            rows = self.pareto()
            doc["library"] = {
                "folder": self.library_folder,
                "strategies": STRATEGY_TEXT,
                "basis": basis,
                "headline": self.library_headline,
                "gaits": [c.record() for c in self.library],
                "skipped": list(self.skipped),
                "pareto": rows,
                "comparison": "each strategy's CoT interpolated linearly in speed between "
                              "its walkable orbits; a speed outside a strategy's range is not "
                              "compared",
            }
        return doc

    def tables(self) -> dict[str, Table]:
        """``energy.csv`` (one row per thrust value) and, with a library,
        ``library_energy.csv`` (one row per library gait at zero thrust) and ``pareto.csv``
        (one row per speed)."""
        notes = ["one row per thrust value; energies per step [J] of the stable periodic orbit "
                 "(exact quadrature on Z, SPEC 15); cot_* = E / (m g d); empty cells: not "
                 "computed (reason column, and energy.json)"]
        notes += [f"empty total cells: {m}" for m in self.missing]
        out = {"energy": Table([col("thrust", "N")] + ROW_HEADER,
                               [[c.thrust] + c.row() for c in self.cases], notes)}
        if self.library is not None:
            out["library_energy"] = Table(
                ["gait", "file", col("target_speed", "m/s")] + ROW_HEADER,
                [[c.label, c.file, c.target_speed] + c.row() for c in self.library],
                ["one row per library gait designed without thrust, at zero thrust; columns "
                 "as energy.csv"] + [f"empty total cells: {m}" for m in self.missing])
            basis = self.basis
            out["pareto"] = Table(
                [col("speed", "m/s"), f"cot_{basis}_designed", f"cot_{basis}_thrust",
                 "cheapest", "compared"],
                [[r["speed"], r[DESIGNED], r[PUSHED], r["cheapest"], r["compared"]]
                 for r in self.pareto()],
                [f"{basis} CoT of each strategy at each speed of either curve, linear "
                 "interpolation in speed between walkable orbits: designed = "
                 f"{STRATEGY_TEXT[DESIGNED]}; "
                 f"thrust = {STRATEGY_TEXT[PUSHED]}; empty: the speed is outside that "
                 "strategy's range (compared false)"])
        return out

    def figures(self, titles: bool = False) -> dict:
        """``cot_speed`` (CoT against speed over the thrust values, mechanical and total,
        legs / thrust split), ``power_step`` (power along the step at the nominal and the
        extreme thrust, joints and thrusters stacked) and, with a library, ``pareto``."""
        from ..plots.energy import cot_speed_figure, pareto_figure, power_step_figure

        w = self.walker
        label = self.thruster_name or "thrust"
        curves = {}
        for basis in ("mechanical", "total"):
            pts = [(c.speed(), c.cot()[basis], c.cot()[basis + "_legs"], c.thrust, c.walkable)
                   for c in self.cases if c.energy is not None
                   and c.cot()[basis] is not None]
            curves[basis] = pts
        why_total = "" if curves["total"] else (
            f"total CoT not computed:\n{len(self.missing)} model(s) missing (energy.json)"
            if self.missing else "no stable orbit")
        out = {"cot_speed": cot_speed_figure(
            curves, thruster=label, note_total=why_total,
            title=f"{w.name}: cost of transport vs speed" if titles else "")}
        nom, ext = self.nominal_extreme()
        panels = []
        basis = self.basis
        for i in dict.fromkeys(x for x in (nom, ext) if x is not None):
            p = self.profiles.get(i)
            if p is None:
                continue
            panels.append((f"{self.cases[i].thrust:g} N" if self.cases[i].thrust is not None
                           else "gait thrust", _stack(p, basis)))
        out["power_step"] = power_step_figure(
            panels, basis=basis, title=f"{w.name}: power along the step" if titles else "")
        if self.library is not None:
            xa, ya, la = _curve(self.library, basis)
            xb, yb, lb = _curve(self.cases, basis)
            env = []  # the cheapest CoT on a fine grid of speeds (where either reaches)
            if xa.size or xb.size:
                lo = min(x[0] for x in (xa, xb) if x.size)
                hi = max(x[-1] for x in (xa, xb) if x.size)
                for v in np.unique(np.concatenate([np.linspace(lo, hi, 301), xa, xb])):
                    c = [y for y in (_interp(v, xa, ya), _interp(v, xb, yb)) if y is not None]
                    env.append((float(v), min(c)) if c else (float(v), float("nan")))
            out["pareto"] = pareto_figure(
                (xa, ya, [c.label for c in la]), (xb, yb, [c.thrust for c in lb]),
                env, basis=basis, gait=w.gait.name, thruster=label,
                title=f"{w.name}: cheapest way to each speed" if titles else "")
        return out


def _stack(p: dict, basis: str) -> dict:
    """The non-negative powers that add up to the CoT's energy (``basis``): per joint and
    per thruster, over time [s]."""
    layers = []
    if basis == "total":
        for name, v in zip(p["joint_names"], p["joint_electrical"]):
            layers.append((f"joint {name}", v))
        for name, v in zip(p["thruster_names"], p["thruster_input"]):
            layers.append((f"thruster {name}", v))
    else:
        for j, name in enumerate(p["joint_names"]):
            layers.append((f"joint {name}", np.maximum(p["joint_mechanical"][:, j], 0.0)))
        for k, name in enumerate(p["thruster_names"]):
            layers.append((f"thruster {name}", np.maximum(p["thrust_mechanical"][:, k], 0.0)))
    return {"time": p["time"], "layers": [(n, v) for n, v in layers if v is not None]}


def energy(walker: Walker, thrust: Sequence[float] | None = None, thruster: str | None = None,
           *, slope: float = 0.0, library: str | Path | None = None) -> EnergyResult:
    """The energy of ``walker``'s gait over constant thrust values ``thrust`` [N] on
    ``thruster`` (default: the first; values default to 0 to -50 N, 0 without thrusters) on
    the ground ``slope`` [rad, positive uphill] (module docstring, SPEC 15), and with
    ``library`` (the folder of a design-gait sweep) every library gait designed without
    thrust at zero thrust and the Pareto comparison of the two strategies."""
    check_walker(walker)
    thrust = check_numbers("thrust", thrust, optional=True)
    check_text("thruster", thruster, optional=True)
    slope = check_number("slope", slope)
    library = check_path("library", library, optional=True)
    entries = None
    if library is not None:
        from ..files.results import read_gait_library

        entries = read_gait_library(library)
    values = (DEFAULT_THRUST if walker.robot.thrusters else (0.0,)) if thrust is None else thrust
    sweep = limit_cycle(walker, values, thruster, slope=slope)
    labels = [f"{v:g} N" for v in sweep.thrust]
    cases = _cases(sweep, labels)
    result = EnergyResult(sweep.walker, sweep, tuple(cases))
    nom, ext = result.nominal_extreme()
    profiles = {}
    for i in dict.fromkeys(x for x in (nom, ext) if x is not None):
        profiles[i] = power_profile(sweep.walker.zd, sweep.schedule.take(np.array([i])),
                                    sweep.cycles[i], samples=PROFILE_SAMPLES)
    lib, skipped = None, []
    if entries is not None:
        lib = []
        for ent in entries:
            w = gait_on_robot(walker.robot, ent.file)
            if w.gait.thrust is not None and np.any(w.gait_schedule().force != 0):
                skipped.append(f"{ent.name}: designed under thrust (its thrust: section), not "
                               "a gait without thrust")
                continue
            lc = limit_cycle(w, [0.0], slope=slope)
            lib += _cases(lc, [ent.name], file=[ent.file],
                          target_speed=[ent.number("target_speed_m_s")])
        if not lib:
            raise InputError.param("library", f"{library}: no gait of the library was designed "
                                              "without thrust")
        lib = tuple(lib)
    return EnergyResult(sweep.walker, sweep, tuple(cases), profiles, lib,
                        None if library is None else str(library), tuple(skipped))
