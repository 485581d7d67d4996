"""The plan and the result of the ``rough-ground`` study (SPEC 14): :class:`RoughGroundPlan`
(made by :func:`.rough_ground.plan_rough_ground`) and :class:`RoughGroundResult` (the
Monte-Carlo and mesh-chain MFPT per strategy and sigma, their agreement, the headline), with
its document, tables and figure; ``DEFINITIONS`` says what each word of it means. Running the
plan is :mod:`.rough_ground`. Units SI, MFPT in steps.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..resilience.mfpt import mc_estimate
from ..resilience.rough import (
    FAILURES,
)
from ..resilience.strategy import Strategy
from ..sweep.runner import RunCounts
from ..sweep.tasks import PointTask
from ..walker import Walker
from .documents import (
    SCHEMA_VERSION,
    Table,
    col,
    gait_record,
    orbit_record,
    result_repr,
    robot_record,
    slope_record,
    units,
)

TARGET = 1000.0  # [steps] the headline's MFPT

UNITS = units("zeta", "speed", "step_time", "step_length", sigma="m", mfpt="steps",
              height="m", output_y="rad")
DEFINITIONS = {
    "mfpt": "mean first passage time: expected steps attempted up to and including the one "
            "that fails (completed steps + 1); 1/p for a per-step failure probability p",
    "outcomes": {
        "censored": "the run reached the cap without failing (counted with its steps, not "
                    "dropped)",
        "fell": "the stance leg passed the horizontal, or no impact came",
        "stopped": "alpha reversed: the walker stopped and fell back",
        "scuffed": "an early strike before the guard was armed (a step up too high), or the "
                   "trailing foot did not lift off at impact",
        "lifted": "the vertical ground force dropped to min_vertical_force, or the impact "
                  "impulse did not press on the ground",
        "slipped": "the stance force or the impact impulse left the friction cone",
        "missed_footing": "no touchdown by s_max (a step down too deep)",
        "error": "the run could not be computed: no verdict (counted as censored at its last "
                 "completed step)",
    },
    "monte_carlo": "geometric MLE T/F (F failures, T steps attempted by every run, censored "
                   "ones included) with the Clopper-Pearson 95 % interval of p = F/T inverted",
    "mesh": "Markov chain on the pre-impact state reduced to (zeta^-, h): zeta^- at an impact "
            "and the height of its ground (the state on Z there; output_error_at_impact: the "
            "largest max |y| left at an impact, what the reduction drops), its transitions "
            "from one-step full-order simulations integrated over the next height's density; "
            "mfpt = 1/(1 - lambda_2), lambda_2 the largest eigenvalue of the transition matrix "
            "among the non-failed states; from_fixed_point = (I - Q)^-1 1 from the level "
            "impact at the fixed point",
    "uncertainty": "the larger |change| of the mesh mfpt with half the mesh points or half the "
                   "terrain samples",
    "agreement": "agree: the mesh's from_fixed_point lies inside the Monte-Carlo 95 % interval "
                 "(with no failure in the Monte-Carlo, above its lower end); disagree "
                 "otherwise; not compared: a side is missing",
}


@dataclass(frozen=True)
class RoughGroundPlan:
    """Everything a rough-ground run computes, checked and keyed before any trial: the
    strategies (made concrete), the sigmas [m], one task per trial (``where``: (strategy,
    sigma, trial) of each) and the mesh settings."""

    walker: Walker = field(repr=False)
    strategies: tuple[Strategy, ...]
    realized: tuple = field(repr=False)
    params: tuple[dict, ...] = field(repr=False)
    sigmas: tuple[float, ...]
    settings: dict
    tasks: tuple[PointTask, ...] = field(repr=False)
    where: tuple[tuple[int, int, int], ...] = field(repr=False)
    identity: str
    warnings: tuple[str, ...] = ()


def crossing(sigmas: Sequence[float], mfpt: Sequence[float | None], target: float
             ) -> tuple[float | None, str]:
    """The sigma [m] where an MFPT curve (None: infinite) first falls through ``target``
    [steps], interpolated linearly in sigma on log(MFPT); None with the reason when it does
    not cross in the range."""
    pts = [(s, np.inf if v is None else float(v)) for s, v in zip(sigmas, mfpt)]
    pts.sort()
    for (s0, v0), (s1, v1) in zip(pts[:-1], pts[1:]):
        if v0 >= target > v1:
            if not np.isfinite(v0):
                return s1, "at the first sigma below the target (the one before has none)"
            a, b = np.log(v0), np.log(v1)
            return float(s0 + (np.log(target) - a) / (b - a) * (s1 - s0)), ""
    if pts and all(v >= target for _, v in pts):
        return None, f"not reached (the MFPT stays above {target:g} steps up to sigma = " \
                     f"{1e3 * pts[-1][0]:g} mm)"
    if pts and pts[0][1] < target:
        return None, f"not reached (the MFPT is already below {target:g} steps at sigma = " \
                     f"{1e3 * pts[0][0]:g} mm)"
    return None, "not reached"


@dataclass(frozen=True)
class RoughGroundResult:
    """The trials of a :class:`RoughGroundPlan` with their records (None: not run), the mesh
    chains per strategy, what this run did and where; renders ``rough_ground.json``,
    ``mfpt.csv``, ``trials.csv`` and the figure ``mfpt``."""

    __repr__ = result_repr

    plan: RoughGroundPlan
    records: tuple[dict | None, ...] = field(repr=False)
    counts: RunCounts
    executor: dict
    meshes: tuple[dict, ...] = field(repr=False)
    mc_time: float = 0.0
    mesh_time: float = 0.0

    name = "rough_ground"

    @property
    def missing(self) -> int:
        """The number of Monte-Carlo trials without a record (run again to resume)."""
        return sum(r is None for r in self.records)

    def _outcome(self, rec: dict | None) -> str | None:
        if rec is None:
            return None
        return rec["fields"]["outcome"] if rec["status"] == "ok" else "error"

    def monte_carlo(self, k: int, i: int) -> dict:
        """The Monte-Carlo estimate of strategy ``k`` at sigma ``i`` (module docstring)."""
        kinds = dict.fromkeys(FAILURES, 0)
        F = T = censored = errors = run = 0
        first_error = ""
        for (kk, ii, _), rec in zip(self.plan.where, self.records):
            if kk != k or ii != i or rec is None:
                continue
            run += 1
            o = self._outcome(rec)
            f = rec["fields"] if rec["status"] == "ok" else {}
            if o in kinds:
                kinds[o] += 1
                F += 1
                T += int(f["attempted"])
            else:
                T += int(f.get("steps_completed") or 0)
                if o == "censored":
                    censored += 1
                else:
                    errors += 1
                    first_error = first_error or (rec["document"] or {}).get("reason") \
                        or rec["reason"]
        est = mc_estimate(F, T) if run else None
        doc = est.document() if est is not None else {"mfpt": None, "ci_lower": None,
                                                      "ci_upper": None, "failures": 0,
                                                      "exposure": 0}
        return {**doc, "trials": run, "censored": censored, "errors": errors,
                "failures_by_kind": kinds, "not_run": self.plan.settings["trials"] - run,
                "first_error": first_error or None}

    @staticmethod
    def agreement(mc: dict, mesh: dict | None) -> str:
        """``agree`` when the mesh chain's MFPT from the fixed point lies in the Monte-Carlo
        interval (SPEC 14), ``disagree``, or ``not compared``."""
        if mesh is None or mc["trials"] == 0:
            return "not compared"
        v, lo, hi = mesh.get("from_fixed_point"), mc["ci_lower"], mc["ci_upper"]
        if mc["failures"] == 0:
            return "agree" if v is None or (lo is not None and v >= lo) else "disagree"
        if v is None:
            return "disagree"
        return "agree" if lo <= v <= (np.inf if hi is None else hi) else "disagree"

    def strategy_summary(self, k: int) -> dict:
        """Strategy ``k``'s entry of ``rough_ground.json``: orbit, mesh, and per sigma [m] the
        Monte-Carlo and mesh MFPT [steps] and their agreement."""
        p = self.plan
        s, real, mesh = p.strategies[k], p.realized[k], self.meshes[k]
        rows = []
        for i, sg in enumerate(p.sigmas):
            mc = self.monte_carlo(k, i)
            m = mesh["sigmas"][i] if mesh["computed"] else None
            rows.append({"sigma": sg, "monte_carlo": mc, "mesh": m,
                         "agreement": self.agreement(mc, m)})
        return {"label": s.label, "strategy": s.parameters(), "zeta_ref": real.zeta_ref,
                "orbit": orbit_record(real.cycle, real.zeta_ref, p.walker.slope,
                                      "the orbit the trials start on"
                                      + (" (the controller's zero-thrust reference)"
                                         if s.kind == "control" else "")),
                "mesh": {kk: v for kk, v in mesh.items() if kk not in ("sigmas", "seconds")},
                "sigmas": rows}

    def headline(self) -> dict:
        """The sigma [m] each strategy tolerates at the target MFPT [steps] on the mesh chain's
        curve, against no thrust (SPEC 14)."""
        p = self.plan
        target = p.settings["target_mfpt"]
        per = []
        for k, s in enumerate(p.strategies):
            mesh = self.meshes[k]
            if not mesh["computed"]:
                per.append({"label": s.label, "sigma": None, "reason": mesh["reason"]})
                continue
            sig, why = crossing(p.sigmas, [r["mfpt"] for r in mesh["sigmas"]], target)
            per.append({"label": s.label, "sigma": sig, "reason": why})
        base = next((h for h in per if h["label"] == "none"), None)
        lines = []
        head = f"at MFPT = {target:,.0f} steps"
        for h in per:
            if base is None or h is base:
                continue
            if h["sigma"] is not None and base["sigma"] is not None:
                lines.append(f"{head}, {h['label']} tolerates sigma = {1e3 * h['sigma']:.3g} mm "
                             f"vs {1e3 * base['sigma']:.3g} mm without thrust")
            else:
                lines.append(f"{head}: {h['label']} " + (
                    f"tolerates sigma = {1e3 * h['sigma']:.3g} mm" if h["sigma"] is not None
                    else h["reason"]) + "; without thrust " + (
                    f"sigma = {1e3 * base['sigma']:.3g} mm" if base["sigma"] is not None
                    else base["reason"]))
        if not lines:
            lines += [f"{head}: {h['label']} " + (
                f"tolerates sigma = {1e3 * h['sigma']:.3g} mm" if h["sigma"] is not None
                else h["reason"]) for h in per]
        return {"target_mfpt": target, "curve": "mesh chain 1/(1 - lambda_2), log-linear in "
                                                  "sigma between grid values",
                "strategies": per, "text": lines}

    def warnings(self) -> list[str]:
        """The warnings of ``rough_ground.json``: the plan's and the trials that could not be
        computed."""
        out = list(self.plan.warnings)
        for k, s in enumerate(self.plan.strategies):
            summ = self.strategy_summary(k)
            errs = sum(r["monte_carlo"]["errors"] for r in summ["sigmas"])
            if errs:
                first = next(r["monte_carlo"]["first_error"] for r in summ["sigmas"]
                             if r["monte_carlo"]["errors"])
                out.append(f"{s.label}: {errs} trial(s) could not be computed (counted as "
                           f"censored at their last step); first: {first}")
            for r in summ["sigmas"]:
                if r["agreement"] == "disagree":
                    out.append(f"{s.label}, sigma = {r['sigma']:g} m: the mesh chain "
                               f"({_g(r['mesh']['from_fixed_point'])} steps) is outside the "
                               f"Monte-Carlo 95 % interval [{_g(r['monte_carlo']['ci_lower'])},"
                               f" {_g(r['monte_carlo']['ci_upper'])}]")
                m = r["mesh"]
                if m is not None and m["clipped_mass"] > 1e-3:
                    out.append(f"{s.label}, sigma = {r['sigma']:g} m: a walker that has not "
                               f"failed leaves the mesh with probability "
                               f"{m['clipped_mass']:.2g} per step (put on its end)")
        if self.missing:
            out.append(f"{self.missing} trial(s) not run: run again to resume")
        return out

    @property
    def success(self) -> bool:
        """Every trial ran, every mesh was computed and no Monte-Carlo estimate disagrees with
        the mesh."""
        return not self.missing and all(
            r["agreement"] != "disagree" for k in range(len(self.plan.strategies))
            for r in self.strategy_summary(k)["sigmas"]) and all(
            m["computed"] for m in self.meshes)

    @property
    def reason(self) -> str:
        """What is missing, where the two estimates disagree, or the headline."""
        if self.missing:
            return f"{self.missing} of {len(self.records)} trials not run (run again to resume)"
        bad = [f"{self.plan.strategies[k].label} at sigma = {r['sigma']:g} m"
               for k in range(len(self.plan.strategies))
               for r in self.strategy_summary(k)["sigmas"] if r["agreement"] == "disagree"]
        if bad:
            return f"the mesh chain and the Monte-Carlo disagree: {', '.join(bad)}"
        nomesh = [m["reason"] for m in self.meshes if not m["computed"]]
        if nomesh:
            return f"no mesh chain: {nomesh[0]}"
        return "every trial run; the mesh chain lies inside the Monte-Carlo interval wherever " \
               "both are computed"

    def document(self) -> dict:
        """The JSON body of ``rough_ground.json`` (SI units, see ``units``)."""
        p, w = self.plan, self.plan.walker
        return {
            "schema_version": SCHEMA_VERSION,
            "units": ({**UNITS, "slope": "rad", "climb_rate": "m/s"} if w.slope != 0.0
                      else UNITS),
            "success": self.success, "reason": self.reason, "warnings": self.warnings(),
            "robot": robot_record(w.zd), "gait": gait_record(w.zd),
            **({"slope": slope_record(w.slope)} if w.slope != 0.0 else {}),
            "settings": p.settings,
            "definitions": DEFINITIONS, "headline": self.headline(),
            "strategies": [self.strategy_summary(k) for k in range(len(p.strategies))],
            "counts": {"trials": len(p.tasks), "recorded": len(p.tasks) - self.missing,
                       "not_run": self.missing, "skipped": self.counts.skipped,
                       "computed": self.counts.ok + self.counts.failed,
                       "resubmitted": self.counts.resubmitted},
            "identity": p.identity, "executor": self.executor,
            "wall_time": {"monte_carlo": self.mc_time, "mesh": self.mesh_time},
            "trials_folder": "trials",
        }

    def tables(self) -> dict[str, Table]:
        """``mfpt`` (one row per strategy and sigma) and ``trials`` (one row per Monte-Carlo
        run)."""
        p = self.plan
        header = ["strategy", col("sigma", "m"), col("mc_mfpt", "steps"),
                  col("mc_ci_lower", "steps"), col("mc_ci_upper", "steps"), "failures",
                  col("exposure", "steps"), "trials", "censored", "errors",
                  *[f"failed_{kd}" for kd in FAILURES], col("mesh_mfpt", "steps"),
                  col("mesh_from_fixed_point", "steps"), "lambda2",
                  col("mesh_uncertainty", "steps"), "agreement"]
        rows = []
        for k in range(len(p.strategies)):
            summ = self.strategy_summary(k)
            for r in summ["sigmas"]:
                mc, m = r["monte_carlo"], r["mesh"] or {}
                rows.append([summ["label"], r["sigma"], mc["mfpt"], mc["ci_lower"],
                             mc["ci_upper"], mc["failures"], mc["exposure"], mc["trials"],
                             mc["censored"], mc["errors"],
                             *[mc["failures_by_kind"][kd] for kd in FAILURES], m.get("mfpt"),
                             m.get("from_fixed_point"), m.get("lambda2"),
                             m.get("uncertainty"), r["agreement"]])
        th = ["trial", "key", "strategy", col("sigma", "m"), "outcome", "steps_completed",
              "attempted", "failed_step", col("failed_height", "m"), "terrain_seed", "reason"]
        trows = []
        for t, (k, _i, tr), rec in zip(p.tasks, p.where, self.records):
            if rec is None:
                continue
            f = rec["fields"] if rec["status"] == "ok" else {}
            doc = rec["document"] or {}
            trows.append([tr, t.key[:20], p.strategies[k].label, dict(t.values)["sigma"],
                          self._outcome(rec), f.get("steps_completed"), f.get("attempted"),
                          f.get("failed_step"), f.get("failed_height"), f.get("terrain_seed"),
                          doc.get("reason") or rec["reason"]])
        return {"mfpt": Table(header, rows, [
                    "one row per (strategy, sigma): Monte-Carlo MFPT with its 95 % interval "
                    "and the mesh chain's (SPEC 14); empty: not computed (no failure, or "
                    "infinite)"]),
                "trials": Table(th, trows, ["one row per Monte-Carlo run; its record is "
                                            "trials/KEY.json"])}

    def figure_data(self) -> dict:
        """The plain data of the ``mfpt`` figure: per strategy the Monte-Carlo and mesh MFPT
        [steps] against sigma [m]."""
        p = self.plan
        out = []
        for k in range(len(p.strategies)):
            summ = self.strategy_summary(k)
            out.append({"label": summ["label"],
                        "mc": [(r["sigma"], r["monte_carlo"]["mfpt"], r["monte_carlo"]["ci_lower"],
                                r["monte_carlo"]["ci_upper"]) for r in summ["sigmas"]
                               if r["monte_carlo"]["trials"]],
                        "mesh": [(r["sigma"], None if r["mesh"] is None else r["mesh"]["mfpt"])
                                 for r in summ["sigmas"]]})
        return {"strategies": out, "target": p.settings["target_mfpt"],
                "cap": p.settings["cap"]}

    def figures(self, titles: bool = False) -> dict:
        """``mfpt``: the mean first passage time [steps] against sigma [m] per strategy (a
        matplotlib figure)."""
        from ..plots import rough_ground as plots

        w = self.plan.walker
        title = f"{w.robot.name} / {w.gait.name}: MFPT on rough ground" if titles else ""
        return {"mfpt": plots.mfpt(self.figure_data(), title)}


def _g(v) -> str:
    return "none" if v is None else f"{v:.4g}"
