"""The plan and the result of the ``robustness`` study (SPEC 12): a :class:`RobustnessPlan`
(made by :func:`.robustness.plan_robustness`) holds every trial and sample to run;
:class:`RobustnessResult` renders them with their records as ``robustness.json`` (the push map,
the largest survivable pushes, the basins, the uncertainty), its CSV tables and its figures;
``DEFINITIONS`` says what each outcome and summary word means. Running the plan is
:mod:`.robustness`. Units SI.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..description.uncertainty import Uncertainty
from ..resilience.maps import (
    mean_of,
    outcome_counts,
    single_outcome,
    spread,
    summary_impulse,
    survivable,
)
from ..resilience.strategy import Realized, Strategy
from ..resilience.trials import OUTCOMES
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
from .trial_studies import ENERGY_FIELDS

UNITS = units("impulse", "zeta", "speed", "step_length", "force", "friction_ratio", "sigma_N",
              "output_rate", "output_y", "step_time", "delta_zero_sq", "alpha", phase="1",
              duration="s")

@dataclass(frozen=True)
class RobustnessPlan:
    """Everything a robustness run computes, checked and keyed before any trial runs: the
    strategies (made concrete for the walker, with their reduced basins), the grids, the
    drawn parameters and one task per trial or sample, in order (``kinds``: ``push``,
    ``basin`` or ``sample`` per task; ``where``: (strategy, i, j) of each)."""

    walker: Walker = field(repr=False)
    strategies: tuple[Strategy, ...]
    realized: tuple[Realized, ...] = field(repr=False)
    settings: dict
    impulses: tuple[float, ...]
    phases: tuple[float, ...]
    sigmas: tuple[float, ...]
    rates: tuple[float, ...]
    uncertainty: Uncertainty | None
    draws: dict[str, tuple[float, ...]]
    tasks: tuple[PointTask, ...] = field(repr=False)
    kinds: tuple[str, ...] = field(repr=False)
    where: tuple[tuple[int, int, int], ...] = field(repr=False)
    identity: str
    warnings: tuple[str, ...] = ()

    @property
    def labels(self) -> list[str]:
        """The label of each strategy, in order."""
        return [s.label for s in self.strategies]



DEFINITIONS = {
    "outcomes": {
        "recovered": "every step walked and the last zeta^- within recovery_tol of the "
                     "strategy's orbit, outputs settled (max |y| <= output_tol)",
        "unsettled": "every step walked, not yet within the tolerance (converging: inside the "
                     "reduced basin and closer each step)",
        "fell": "the stance leg passed the horizontal, or the swing foot missed the ground",
        "slipped": "the push's impulsive ground reaction, a stance force or an impact impulse "
                   "left the friction cone",
        "lifted": "the push's impulsive ground reaction, a stance force (<= min_vertical_force)"
                  " or an impact impulse was not pressing on the ground",
        "scuffed": "the swing foot struck the ground early, or the trailing foot did not lift "
                   "off at impact",
        "stopped": "alpha reversed: the walker stopped and fell back",
        "error": "the trial could not be computed (integrator or controller failure): no "
                 "verdict",
    },
    "survivable": "per phase and direction, the largest grid impulse |P| such that every grid "
                  "impulse of that direction with |p| <= |P| recovered (0 when the smallest did "
                  "not); a lower bound within one grid step; bound: failed / grid edge / error "
                  "/ not run",
    "summary": "mean over phases of (P_forward + P_backward) / 2 [N s], each phase averaging "
               "the directions the impulse grid has",
    "converging_fraction": "basin slice: trials that recovered or are converging, over the "
                           "trials computed (errors and trials not run excluded)",
    "success_rate": "uncertainty: samples that walk, over the samples whose draw is a valid "
                    "robot",
}


@dataclass(frozen=True)
class RobustnessResult:
    """Every trial and sample of a :class:`RobustnessPlan` with its record (None: not run),
    what this run did (``counts``) and where it ran (``executor``); renders
    ``robustness.json``, ``trials.csv`` (and ``uncertainty.csv``) and the figures."""

    __repr__ = result_repr

    plan: RobustnessPlan
    records: tuple[dict | None, ...] = field(repr=False)
    counts: RunCounts
    executor: dict
    wall_time: float

    name = "robustness"

    # -- records -----------------------------------------------------------------------
    def _by_kind(self, kind: str, k: int) -> list[tuple[tuple[int, int], dict | None]]:
        p = self.plan
        return [((w[1], w[2]), r) for kd, w, r in zip(p.kinds, p.where, self.records)
                if kd == kind and w[0] == k]

    @staticmethod
    def _outcome(rec: dict | None) -> str | None:
        if rec is None:
            return None
        if rec["status"] != "ok":
            return "error"
        return rec["fields"]["outcome"]

    def push_grid(self, k: int) -> list[list[str | None]]:
        """Outcome per (phase, impulse) of strategy ``k`` (None: not run)."""
        p = self.plan
        grid: list[list[str | None]] = [[None] * len(p.impulses) for _ in p.phases]
        for (i, j), r in self._by_kind("push", k):
            grid[i][j] = self._outcome(r)
        return grid

    def slice_grid(self, k: int) -> tuple[list[list[str | None]], list[list[bool | None]]]:
        """Outcome and converging flag per (sigma, rate) of strategy ``k``."""
        p = self.plan
        out = [[None] * len(p.rates) for _ in p.sigmas]
        conv: list[list[bool | None]] = [[None] * len(p.rates) for _ in p.sigmas]
        for (i, j), r in self._by_kind("basin", k):
            out[i][j] = self._outcome(r)
            if r is not None and r["status"] == "ok":
                conv[i][j] = bool(r["fields"]["converging"])
        return out, conv

    def samples(self, k: int) -> list[dict | None]:
        """Strategy ``k``'s record of each parameter sample (None: not run yet)."""
        return [r for _, r in self._by_kind("sample", k)]

    def _trial_records(self) -> list[tuple[str, dict | None]]:
        return [(kd, r) for kd, r in zip(self.plan.kinds, self.records) if kd != "sample"]

    @property
    def errors(self) -> int:
        """The number of trials that could not be computed (outcome ``error``)."""
        return sum(self._outcome(r) == "error" for _, r in self._trial_records())

    @property
    def missing(self) -> int:
        """The number of trials and samples without a record (run again to resume)."""
        return sum(r is None for r in self.records)

    @property
    def success(self) -> bool:
        """Every trial and sample has its record and no trial failed to compute."""
        return self.missing == 0 and self.errors == 0

    # -- summaries ---------------------------------------------------------------------
    def strategy_summary(self, k: int) -> dict:
        """Strategy ``k``'s entry of ``robustness.json`` (SPEC 12): orbit, reduced basin, push
        outcomes, survivable impulses [N s], energies [J]."""
        p = self.plan
        s, real = p.strategies[k], p.realized[k]
        grid = self.push_grid(k)
        rows = []
        for i, ph in enumerate(p.phases):
            f, fb = survivable(p.impulses, grid[i], 1.0)
            b, bb = survivable(p.impulses, grid[i], -1.0)
            rows.append({"phase": ph, "forward": f, "forward_bound": fb, "backward": b,
                         "backward_bound": bb})
        fwd, bwd = [r["forward"] for r in rows], [r["backward"] for r in rows]
        flat = [o for row in grid for o in row]
        single = {name: single_outcome(list(p.impulses) * len(p.phases), flat, sign)[0]
                  for name, sign in (("forward", 1.0), ("backward", -1.0))}
        lc = real.cycle
        out = {
            "label": s.label, "kind": s.kind, "parameters": s.parameters(),
            "notes": list(real.notes),
            "orbit": orbit_record(lc, real.zeta_ref, p.walker.slope,
                                  "the controller's reference (the zero-thrust orbit)"
                                  if s.kind == "control" else "the strategy's own fixed point"),
            "reduced_basin": real.basin.document(),
            "push": {"outcome_counts": outcome_counts(flat, OUTCOMES),
                     "recovered_fraction": _fraction(flat, ("recovered",)),
                     "survivable": rows, "mean_forward": mean_of(fwd),
                     "mean_backward": mean_of(bwd), "summary": summary_impulse(fwd, bwd),
                     "single_outcome": single},
        }
        out["push"]["energy"] = self._energy_summary(k)
        if p.sigmas:
            out["basin_slice"] = self._slice_summary(k)
        if p.uncertainty is not None:
            out["uncertainty"] = self._sample_summary(k)
        return out

    def push_energies(self, k: int, key: str = "energy_mechanical"
                      ) -> list[list[float | None]]:
        """The field ``key`` (an energy of ``trial_studies.ENERGY_FIELDS``) [J] per
        (phase, impulse) of strategy ``k``'s recovered push trials; None where not
        recovered (or the energy is missing)."""
        p = self.plan
        grid: list[list[float | None]] = [[None] * len(p.impulses) for _ in p.phases]
        for (i, j), r in self._by_kind("push", k):
            if self._outcome(r) == "recovered":
                grid[i][j] = r["fields"].get(key)
        return grid

    def _energy_summary(self, k: int) -> dict:
        """Per strategy: the mean over its recovered push trials of the energy each spent
        (SPEC 15, ``trial_studies.trial_energy``) [J], each part None when a model is
        missing (``reason``) or nothing recovered; and the same less the energy of the trial
        without a push (impulse 0 in the grid: ``extra_over_unpushed``; None without one)."""
        recs = [r for _, r in self._by_kind("push", k) if self._outcome(r) == "recovered"]
        keys = ("energy_mechanical", "energy_total", "energy_legs_mechanical",
                "energy_legs_electrical", "energy_thrust_mechanical", "energy_thrust_input",
                "push_energy")

        def mean(rows, key):
            vals = [r["fields"].get(key) for r in rows]
            if not vals or any(v is None for v in vals):
                return None
            return float(np.mean(vals))

        means = {key: mean(recs, key) for key in keys}
        reasons = []
        for r in recs:
            why = r["fields"].get("energy_reason")
            if why and why not in reasons:
                reasons.append(why)
        if not recs:
            reasons.append("no push trial recovered: no energy per recovered push")
        zero = [r for (i, j), r in self._by_kind("push", k)
                if self.plan.impulses[j] == 0.0 and self._outcome(r) == "recovered"]
        extra = None
        if zero and recs:
            extra = {key: (None if means[key] is None or mean(zero[:1], key) is None
                           else means[key] - mean(zero[:1], key)) for key in keys[:6]}
        elif recs:
            reasons.append("no recovered trial without a push (impulse 0 in the grid): no "
                           "extra energy")
        return {"recovered_pushes": len(recs), "mean_per_recovered_push": means,
                "extra_over_unpushed": extra, "reason": "; ".join(reasons) or None}

    def _slice_summary(self, k: int) -> dict:
        p, real = self.plan, self.plan.realized[k]
        outs, conv = self.slice_grid(k)
        flags = [c for row in conv for c in row if c is not None]
        frac = sum(flags) / len(flags) if flags else None
        agree = None
        if 0.0 in p.rates and real.zeta_ref is not None:
            j0 = p.rates.index(0.0)
            rows = []
            for i, sg in enumerate(p.sigmas):
                x = real.zeta_ref * (1.0 + sg) ** 2
                c = conv[i][j0]
                if c is None:
                    continue
                red = real.basin.contains(x)
                rows.append({"start_sigma": sg, "zeta_minus": x, "reduced": red,
                             "full_order": c})
            agree = {"points": len(rows), "agree": sum(r["reduced"] == r["full_order"]
                                                        for r in rows),
                     "disagreements": [r for r in rows if r["reduced"] != r["full_order"]]}
        return {"converging_fraction": frac, "trials": len(flags),
                "outcome_counts": outcome_counts([o for row in outs for o in row], OUTCOMES),
                "along_sigma_at_zero_rate": agree}

    def _sample_summary(self, k: int) -> dict:
        recs = self.samples(k)
        valid = [r for r in recs if r is not None and r["status"] == "ok"]
        invalid = [r for r in recs if r is not None and r["status"] != "ok"]
        walks = [r for r in valid if r["fields"]["walks"]]
        reasons: dict[str, int] = {}
        for r in valid:
            if not r["fields"]["walks"]:
                why = r["document"]["reason"].split(":")[0]
                reasons[why] = reasons.get(why, 0) + 1
        return {"samples": len(recs), "valid": len(valid), "invalid_draws": len(invalid),
                "first_invalid": invalid[0]["reason"] if invalid else None,
                "not_run": sum(r is None for r in recs), "walking": len(walks),
                "success_rate": len(walks) / len(valid) if valid else None,
                "speed": spread([r["fields"]["speed"] for r in walks]),
                "zeta_star": spread([r["fields"]["zeta_star"] for r in walks]),
                "failures": reasons}

    @property
    def reason(self) -> str:
        """What ran (trials, samples), what could not be computed or is missing, and each
        strategy's survivable push [N s]."""
        p = self.plan
        n = sum(kd != "sample" for kd in p.kinds)
        parts = [f"{n} trials of {len(p.strategies)} strategies"]
        if p.uncertainty is not None:
            parts.append(f"{sum(kd == 'sample' for kd in p.kinds)} parameter samples")
        text = ", ".join(parts)
        if self.errors:
            text += f"; {self.errors} trial(s) could not be computed"
        if self.missing:
            text += f"; {self.missing} not run (run again to resume)"
        sums = []
        for k, s in enumerate(p.strategies):
            v = self.strategy_summary(k)["push"]["summary"]
            sums.append(f"{s.label} {v:.3g} N s" if v is not None else f"{s.label} -")
        text += "; survivable impulse (mean over phases): " + ", ".join(sums)
        for note in self._single_outcomes():
            text += f"; {note['short']}"
        return text

    def _single_outcomes(self) -> list[dict]:
        """Push directions in which one outcome covers every trial (of two or more sizes,
        every phase) of one or more strategies: there the survivable push is 0 N s (or the
        grid's edge, all recovered) at every phase whatever the strategy, so it does not
        tell them apart. One note per (direction, outcome): the strategies, a short text
        for the summary and the full one, with what to change, for the warnings."""
        p = self.plan
        notes = []
        trials = {(kd, w[0], w[1], w[2]): r for kd, w, r in zip(p.kinds, p.where, self.records)}
        for name, sign in (("forward", 1.0), ("backward", -1.0)):
            by: dict[str, list[int]] = {}
            for k in range(len(p.strategies)):
                o = self.strategy_summary(k)["push"]["single_outcome"][name]
                if o is not None and o != "error":
                    by.setdefault(o, []).append(k)
            for o, ks in by.items():
                labels = [p.strategies[k].label for k in ks]
                every = len(ks) == len(p.strategies)
                sizes = sorted({abs(v) for v in p.impulses if v * sign > 0})
                who = ("every strategy" if every and len(ks) > 1 else
                       f"{'strategy' if len(ks) == 1 else 'strategies'} {', '.join(labels)}")
                short = f"every {name} push of {who} is {o}"
                if o == "recovered":
                    value = f"the grid's largest ({sizes[-1]:g} N s)"
                    fix = (f"larger impulses (`push_impulse` beyond {sizes[-1]:g} N s) find "
                           f"where it ends")
                else:
                    value = "0 N s"
                    by_push = all(
                        self._outcome(r) != o or str((r.get("document") or {}).get("reason", "")
                                                     ).startswith("step 1: the push ")
                        for (kd, k, i, j), r in trials.items()
                        if kd == "push" and k in ks and r is not None
                        and p.impulses[j] * sign > 0)
                    why = ("the push's impulsive ground reaction itself (linear in the "
                           "impulse: whether it lifts or slips the stance foot depends on the "
                           "phase, direction and point, not on the size)" if by_push else
                           "the stance foot's reaction to it")
                    fix = (f"decided by {why}; a push spread over time (`push_duration` T "
                           f"> 0 s, e.g. 0.05: the stance force over T is added to the "
                           f"reaction, SPEC 12, so small pushes pass and large ones do not) "
                           f"or at another point or direction (`push_link`, `push_at`, "
                           f"`push_direction`) makes the map depend on the size")
                full = (f"every {name} push ({len(sizes)} sizes x {len(p.phases)} phases) of "
                        f"{who} is `{o}`: the {name} survivable push is {value} at every "
                        f"phase{' for all of them' if len(ks) > 1 else ''}, so it does not "
                        f"tell the strategies apart; {fix}")
                hint = ("; widen `push_impulse`" if o == "recovered" else
                        "; try `push_duration` > 0 or another push point (warnings)")
                notes.append({"direction": name, "outcome": o, "strategies": labels,
                              "short": f"{short}: the {name} survivable push is {value} "
                                       f"whatever the strategy{hint}", "warning": full})
        return notes

    def warnings(self) -> list[str]:
        """The warnings of ``robustness.json``: the plan's, single-outcome push maps, trials that
        could not be computed."""
        out = list(self.plan.warnings)
        out += [n["warning"] for n in self._single_outcomes()]
        bad = [r for kd, r in self._trial_records() if self._outcome(r) == "error"]
        if bad:
            first = (bad[0]["document"] or {}).get("reason") or bad[0]["reason"]
            out.append(f"{len(bad)} trial(s) could not be computed (outcome error, no verdict); "
                       f"first: {first}")
        if self.missing:
            out.append(f"{self.missing} trial(s) or sample(s) not run: run again to resume")
        if self.plan.uncertainty is not None:
            for k, s in enumerate(self.plan.strategies):
                u = self._sample_summary(k)
                if u["invalid_draws"]:
                    out.append(f"{s.label}: {u['invalid_draws']} draw(s) are not a valid robot "
                               f"(excluded from the success rate); first: {u['first_invalid']}")
        return out

    def document(self) -> dict:
        """The JSON body of ``robustness.json`` (SI units, see ``units``)."""
        p, w = self.plan, self.plan.walker
        n_trials = sum(kd != "sample" for kd in p.kinds)
        return {
            "schema_version": SCHEMA_VERSION,
            "units": ({**UNITS, "slope": "rad", "climb_rate": "m/s"} if w.slope != 0.0
                      else UNITS),
            "success": self.success, "reason": self.reason, "warnings": self.warnings(),
            "robot": robot_record(w.zd), "gait": gait_record(w.zd),
            **({"slope": slope_record(w.slope)} if w.slope != 0.0 else {}),
            "settings": p.settings, "definitions": DEFINITIONS,
            "strategies": [self.strategy_summary(k) for k in range(len(p.strategies))],
            "counts": {"trials": n_trials, "samples": len(p.kinds) - n_trials,
                       "recorded": len(p.kinds) - self.missing, "errors": self.errors,
                       "not_run": self.missing, "skipped": self.counts.skipped,
                       "computed": self.counts.ok + self.counts.failed,
                       "resubmitted": self.counts.resubmitted},
            "identity": p.identity, "executor": self.executor, "wall_time": self.wall_time,
            "trials_folder": "trials",
        }

    def tables(self) -> dict[str, Table]:
        """``trials`` (one row per trial) and, with parameter uncertainty, ``uncertainty`` (one
        row per sample and strategy)."""
        p = self.plan
        header = ["trial", "key", "kind", "strategy", "push_phase", col("push_impulse", "N s"),
                  col("push_x", "N s"), col("push_y", "N s"), "start_sigma",
                  col("start_rate", "rad/s"), "outcome", "step", "recovered", "converging",
                  "steps_completed", col("final_zeta_minus", UNITS["zeta"]), "relative_error",
                  col("zeta_ref", UNITS["zeta"]), col("speed", "m/s"), "max_friction_ratio",
                  col("min_vertical_force", "N"), "push_friction_ratio",
                  col("push_vertical_impulse", "N s")] + [
                  col(e, "J") for e in ENERGY_FIELDS] + ["energy_steps", "energy_reason",
                                                         "reason"]
        terrain = p.settings.get("terrain") is not None
        rows = []
        for t, kd, wh, r in zip(p.tasks, p.kinds, p.where, self.records):
            if kd == "sample" or r is None:
                continue
            v = dict(t.values)
            f = r["fields"] if r["status"] == "ok" else {}
            doc = r["document"] or {}
            vec = (doc.get("trial") or {}).get("push_vector") or [None, None]
            rows.append([t.index, t.key[:20], kd, p.strategies[wh[0]].label,
                         v.get("push_phase"), v.get("push_impulse"), vec[0], vec[1],
                         v.get("start_sigma"), v.get("start_rate"), self._outcome(r),
                         f.get("failed_step"), f.get("recovered"), f.get("converging"),
                         f.get("steps_completed"), f.get("final_zeta_minus"),
                         f.get("relative_error"), f.get("zeta_ref"), f.get("speed"),
                         f.get("max_friction_ratio"), f.get("min_vertical_force"),
                         f.get("push_friction_ratio"), f.get("push_vertical_impulse")]
                        + [f.get(e) for e in ENERGY_FIELDS]
                        + [f.get("energy_steps"), f.get("energy_reason"),
                           doc.get("reason") or r["reason"]])
            if terrain:  # SPEC 14: the ground of the failed step (empty: no failure)
                rows[-1].insert(12, f.get("failed_height"))
        notes = ["one row per trial: push trials (pushed in step 1 on the strategy's orbit) and "
                 "basin trials (started off the orbit); the full record is trials/KEY.json"]
        if terrain:
            header.insert(12, col("failed_height", "m"))
            notes.append("failed_height: the terrain height of the failed step (empty: every "
                         "step walked)")
        out = {"trials": Table(header, rows, notes)}
        if p.uncertainty is not None:
            names = list(p.draws)
            units_of = {a.name: a.unit for a in p.uncertainty.axes}
            uh = ["sample", "strategy"] + [col(n.replace(".", "_"), units_of[n]) for n in names] \
                + ["walks", col("zeta_star", UNITS["zeta"]), col("speed", "m/s"),
                   col("step_time", "s"), "controlled_steps", "reason"]
            urows = []
            for t, kd, wh, r in zip(p.tasks, p.kinds, p.where, self.records):
                if kd != "sample" or r is None:
                    continue
                v = dict(t.values)
                f = r["fields"] if r["status"] == "ok" else {}
                doc = r["document"] or {}
                urows.append([wh[1], p.strategies[wh[0]].label] + [v[n] for n in names]
                             + [f.get("walks"), f.get("zeta_star"), f.get("speed"),
                                f.get("step_time"), f.get("controlled_steps"),
                                doc.get("reason") or r["reason"]])
            out["uncertainty"] = Table(uh, urows, ["one row per (sample, strategy)"])
        return out

    # -- figures -----------------------------------------------------------------------
    def figure_data(self) -> dict:
        """The plain data the figures draw: push outcomes, survivable impulses, energies, basins,
        samples."""
        p = self.plan
        sums = [self.strategy_summary(k) for k in range(len(p.strategies))]
        # the total energy when every strategy has it (every model given), else mechanical
        ekind = ("total" if sums and all(s["push"]["energy"]["mean_per_recovered_push"]
                                         ["energy_total"] is not None for s in sums)
                 else "mechanical")
        ekey = f"energy_{ekind}"
        data = {
            "labels": p.labels, "phases": list(p.phases), "impulses": list(p.impulses),
            "outcomes": list(OUTCOMES), "push_maps": [self.push_grid(k)
                                                       for k in range(len(p.strategies))],
            "survivable": [s["push"]["survivable"] for s in sums],
            "summary": [s["push"]["summary"] for s in sums],
            "energy_kind": ekind,
            "push_energy": [self.push_energies(k, ekey) for k in range(len(p.strategies))],
            "energy_mean": [s["push"]["energy"]["mean_per_recovered_push"][ekey]
                            for s in sums],
            "reduced": [{"label": s["label"], **s["reduced_basin"]} for s in sums],
            "sigmas": list(p.sigmas), "rates": list(p.rates),
            "joint": p.settings["basin_slice"]["joint"], "slices": [], "uncertainty": None,
        }
        for k, real in enumerate(p.realized):
            if not p.sigmas:
                break
            outs, conv = self.slice_grid(k)
            zs = real.zeta_ref
            b = real.basin
            rel = [None if (v is None or zs is None or v <= 0) else float(np.sqrt(v / zs) - 1)
                   for v in (b.lower.value, b.upper.value)]
            data["slices"].append({"label": p.strategies[k].label, "outcomes": outs,
                                   "converging": conv, "reduced_sigma": rel,
                                   "basin_exists": b.exists,
                                   "fraction": sums[k]["basin_slice"]["converging_fraction"]})
        if p.uncertainty is not None:
            data["uncertainty"] = [{"label": s["label"],
                                    "speeds": [r["fields"]["speed"] for r in self.samples(k)
                                               if r is not None and r["status"] == "ok"
                                               and r["fields"]["walks"]],
                                    "rate": s["uncertainty"]["success_rate"],
                                    "valid": s["uncertainty"]["valid"]}
                                   for k, s in enumerate(sums)]
            data["nominal_speed"] = [s["orbit"]["speed"] for s in sums]
        return data

    def figures(self, titles: bool = False) -> dict:
        """``push_map``, ``survivable_push``, ``push_energy``, ``basin`` and, with uncertainty,
        ``uncertainty`` (matplotlib figures by stem)."""
        from ..plots import robustness as plots

        d = self.figure_data()
        w = self.plan.walker
        head = f"{w.robot.name} / {w.gait.name}: " if titles else None

        def t(what: str) -> str:
            return head + what if head else ""

        out = {"push_map": plots.push_map(d, t("push outcomes")),
               "survivable_push": plots.survivable_push(d, t("largest survivable push")),
               "push_energy": plots.push_energy(d, t("energy per recovered push"))}
        out["basin"] = plots.basin(d, t("basins of attraction"))
        if d["uncertainty"] is not None:
            out["uncertainty"] = plots.uncertainty(d, t("parameter uncertainty"))
        return out


def _fraction(outcomes: Sequence[str | None], good: tuple[str, ...]) -> float | None:
    done = [o for o in outcomes if o is not None and o != "error"]
    return sum(o in good for o in done) / len(done) if done else None
