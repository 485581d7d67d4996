"""thrustwalk rough-ground (SPEC 14): the mean first passage time on rough ground by Monte-Carlo
and by the mesh Markov chain.

The estimators are checked on synthetic data against the truth they estimate (geometric
failures, a hand-made chain, a one-step map whose failure set is known); the full pipeline on
the 3-link walker against itself two independent ways (Monte-Carlo of full-order runs and the
mesh chain), and against the limit sigma -> 0 (no failure)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from thrustwalk_cli.resilience.mfpt import chain_mfpt, interpolation_weights, mc_estimate
from thrustwalk_cli.resilience.rough import StepMap, transition_matrix
from thrustwalk_cli.studies.rough_ground import (
    plan_rough_ground,
    rough_ground,
    run_rough_ground,
)
from thrustwalk_cli.studies.rough_ground_result import crossing

DATA = __import__("pathlib").Path(__file__).parent / "data"


# ----------------------------------------------------------------------- the estimators
def _experiment(rng, p: float, n: int, cap: int) -> tuple[int, int]:
    """``n`` runs failing each step with probability ``p``, stopped at ``cap`` steps:
    (failures, steps attempted)."""
    attempts = rng.geometric(p, n)  # the step that fails, 1-based
    failed = attempts <= cap
    return int(failed.sum()), int(np.where(failed, attempts, cap).sum())


@pytest.mark.parametrize("p, n, cap", [(0.02, 30, 10_000), (0.02, 40, 20)])
def test_the_monte_carlo_interval_covers_the_true_mfpt_95_percent_of_the_time(p, n, cap):
    """200 synthetic experiments of geometric failures (no simulation), without censoring and
    with a cap far below the mean (most runs censored, counted with their steps): the 95 %
    interval holds the true MFPT 1/p in at least 93 % of them (Clopper-Pearson is exact or
    conservative), and the estimates centre on it."""
    rng = np.random.default_rng(20240527)
    hits, est = 0, []
    for _ in range(200):
        F, T = _experiment(rng, p, n, cap)
        e = mc_estimate(F, T)
        lo, hi = e.ci
        hits += (lo <= 1 / p) and (hi is None or 1 / p <= hi)
        if e.mfpt is not None:
            est.append(e.p)
    assert hits / 200 >= 0.93
    assert np.mean(est) == pytest.approx(p, rel=0.1)  # p = F/T, the MLE, nearly unbiased


def test_censored_runs_are_counted_not_dropped():
    """With the cap far below the mean, dropping the censored runs would estimate the mean of
    the few early failures (about cap/2); counting their steps recovers 1/p."""
    rng = np.random.default_rng(7)
    F, T = _experiment(rng, 0.002, 2000, 50)
    e = mc_estimate(F, T)
    assert F < 0.2 * 2000  # mostly censored
    assert e.ci[0] <= 500.0 <= e.ci[1]
    assert e.mfpt == pytest.approx(500.0, rel=0.15)
    none = mc_estimate(0, 300)  # no failure: no estimate, a lower bound
    assert none.mfpt is None and none.ci[1] is None
    assert none.ci[0] == pytest.approx(1.0 / (1.0 - 0.025 ** (1 / 300)), rel=1e-9)


def test_the_mfpt_of_hand_made_3_state_chains_is_the_analytic_value():
    """A chain failing with probability p from every state, whatever its moves: lambda_2 =
    1 - p and the expected steps 1/p from anywhere. An upper-triangular chain: its
    eigenvalues are the diagonal, (I - Q) m = 1 solved by back-substitution by hand."""
    P = np.array([[0.2, 0.5, 0.3], [0.6, 0.1, 0.3], [0.25, 0.25, 0.5]])
    c = chain_mfpt(0.97 * P, np.array([0.0, 1.0, 0.0]))
    assert c.lambda2 == pytest.approx(0.97, abs=1e-12)
    assert c.mfpt == pytest.approx(1 / 0.03, rel=1e-10)
    assert c.from_start == pytest.approx(1 / 0.03, rel=1e-10)
    a, b, cc, d, e = 0.5, 0.3, 0.9, 0.05, 0.8
    Q = np.array([[a, b, 0.0], [0.0, cc, d], [0.0, 0.0, e]])
    m3 = 1 / (1 - e)
    m2 = (1 + d * m3) / (1 - cc)
    m1 = (1 + b * m2) / (1 - a)
    r = chain_mfpt(Q, np.array([1.0, 0.0, 0.0]))
    assert r.lambda2 == pytest.approx(0.9, abs=1e-12)
    assert r.mfpt == pytest.approx(10.0, rel=1e-10)
    assert r.from_start == pytest.approx(m1, rel=1e-10)
    ones = chain_mfpt(P, np.array([1.0, 0.0, 0.0]))  # stochastic: no failure
    assert ones.mfpt is None and "no failure" in ones.reason


def test_interpolation_weights_keep_the_mean():
    g = np.array([0.0, 1.0, 3.0])
    i, t, clip = interpolation_weights(g, np.array([0.25, 2.0, 3.0, 5.0]))
    mean = g[i] * (1 - t) + g[i + 1] * t
    assert mean.tolist() == [0.25, 2.0, 3.0, 3.0] and clip.tolist() == [False] * 3 + [True]


@pytest.mark.parametrize("distribution", ["normal", "uniform"])
def test_the_transition_matrix_integrates_a_known_failure_set_exactly(distribution):
    """A one-step map that keeps zeta^- and fails iff |h| > e (bracketed at e to 1e-7): the
    failure probability per step is P(|h| > e) of the distribution, in closed form, so the
    MFPT is 1/P from every state."""
    e, sigma = 0.01, 0.006
    grid = np.linspace(-0.03, 0.03, 13)
    h = np.sort(np.concatenate([grid, [-e - 1e-7, -e, e, e + 1e-7]]))
    z = np.array([1.0, 2.0, 3.0])
    hp = np.array([-0.005, 0.0, 0.005])
    rows = tuple(tuple(h for _ in hp) for _ in z)
    zeta = tuple(tuple(np.where(np.abs(h) > e, np.nan, zi) for _ in hp) for zi in z)
    grid_flag = tuple(tuple(np.isin(h, grid) for _ in hp) for _ in z)
    smap = StepMap(z, hp, grid, rows, zeta, grid_flag, {}, 0.0, 0)
    ch = transition_matrix(smap, distribution, sigma)
    if distribution == "normal":
        p = math.erfc(e / (sigma * math.sqrt(2.0)))
    else:
        w = math.sqrt(3.0) * sigma
        p = 1.0 - e / w
    assert ch.fail == pytest.approx(np.full(9, p), rel=1e-4)
    c = chain_mfpt(ch.Q, ch.weights(2.0, 0.0))
    assert c.mfpt == pytest.approx(1 / p, rel=1e-4)
    assert c.from_start == pytest.approx(1 / p, rel=1e-4)
    # the chain keeps zeta^-: every row's mass stays on its own zeta^- (any next height)
    Q = ch.Q.reshape(3, 3, 3, 3)
    for i in range(3):
        assert Q[i, :, i, :].sum() == pytest.approx(3 * (1 - p), rel=1e-4)
        assert Q[i, :, [k for k in range(3) if k != i], :].sum() == 0.0


def test_crossing_of_the_target():
    s, why = crossing([0.001, 0.002, 0.003], [1e5, 100.0, 10.0], 1000.0)
    assert s == pytest.approx(0.001 + 0.001 * 2 / 3) and not why  # log 1e5 -> log 1e2
    assert crossing([0.001, 0.002], [None, 5e4], 1000.0)[0] is None
    assert "not reached" in crossing([0.001, 0.002], [500.0, 50.0], 1000.0)[1]


# ----------------------------------------------------------------------- the walker
SIGMAS = [0.004, 0.0045, 0.005]  # [m] MFPT about 70, 35, 20 steps on the 3-link walker


@pytest.fixture(scope="module")
def agree(walker3):
    """Monte-Carlo (40 runs per sigma, cap 300) and a coarse mesh chain on the 3-link walker."""
    return rough_ground(walker3, sigma=SIGMAS, strategy=["none"], trials=40, cap=300,
                        workers=1, mesh=8, terrain_samples=12, seed=0)


@pytest.mark.slow
def test_monte_carlo_and_the_mesh_chain_agree_on_three_sigmas(agree):
    """The mesh chain's expected steps from the fixed point lie inside the Monte-Carlo 95 %
    interval at each of three sigmas where failures come within tens of steps; the failures
    are the geometric ones of this walker (a step up past the swing foot's apex scuffs, a step
    down past the continued polynomial's lowest point misses its footing)."""
    doc = agree.document()
    rows = doc["strategies"][0]["sigmas"]
    assert [r["agreement"] for r in rows] == ["agree"] * 3, rows
    for r in rows:
        mc, m = r["monte_carlo"], r["mesh"]
        assert mc["ci_lower"] <= m["from_fixed_point"] <= mc["ci_upper"]
        assert mc["failures"] == 40 and mc["censored"] == 0
        assert set(k for k, v in mc["failures_by_kind"].items() if v) <= {"scuffed",
                                                                          "missed_footing"}
        assert m["lambda2"] == pytest.approx(1 - 1 / m["mfpt"])
    mfpt = [r["mesh"]["mfpt"] for r in rows]
    assert mfpt[0] > mfpt[1] > mfpt[2]
    assert doc["success"] and "agree" in doc["definitions"]["agreement"]


def test_no_failure_as_sigma_goes_to_zero(walker3):
    """sigma = 1e-9 m: every Monte-Carlo run reaches the cap (censored, no estimate but a
    lower bound) and the mesh chain's lambda_2 is 1 to rounding (no finite MFPT)."""
    res = rough_ground(walker3, sigma=[1e-9], strategy=["none"], trials=3, cap=100,
                       workers=1, mesh=4, terrain_samples=4)
    row = res.document()["strategies"][0]["sigmas"][0]
    mc, m = row["monte_carlo"], row["mesh"]
    assert mc["failures"] == 0 and mc["censored"] == 3 and mc["exposure"] == 300
    assert mc["mfpt"] is None and mc["ci_lower"] > 80
    assert m["lambda2"] == pytest.approx(1.0, abs=1e-12) and m["mfpt"] is None
    assert "no failure" in m["reason"]
    assert row["agreement"] == "agree"


def _strip(res):
    return [None if r is None else {k: v for k, v in r.items() if k != "seconds"}
            for r in res.records]


def test_a_stopped_run_resumes_to_the_same_result(walker3):
    """A run stopped after some records (the caller raises) resumes with the records it has:
    none is computed again, and every record and the document equal an uninterrupted run."""
    plan = plan_rough_ground(walker3, sigma=[0.005], strategy=["none", "constant:-20"],
                             trials=6, cap=100, mesh=4, terrain_samples=4)
    mesh = [{"computed": False, "reason": "not asked", "sigmas": []}] * 2
    ref = run_rough_ground(plan, workers=1, meshes=mesh, chunk=1)

    class Stop(Exception):
        pass

    kept: dict[str, dict] = {}

    def on_record(rec):
        kept[rec["key"]] = rec
        if len(kept) == 5:
            raise Stop

    with pytest.raises(Stop):
        run_rough_ground(plan, workers=1, meshes=mesh, on_record=on_record)
    computed = []
    res = run_rough_ground(plan, workers=1, finished=dict(kept), meshes=mesh,
                           on_record=lambda r: computed.append(r["key"]))
    assert res.counts.skipped == 5 and not set(computed) & set(kept)
    assert _strip(res) == _strip(ref)
    a, b = res.document(), ref.document()
    for d in (a, b):
        for key in ("counts", "executor", "wall_time"):
            d.pop(key)
    assert a == b


@pytest.mark.slow
def test_a_trial_is_the_same_on_a_dask_cluster(walker3, tmp_path):
    """A scheduler and a worker as separate processes on 127.0.0.1: every trial's record
    equals the one computed in this process."""
    pytest.importorskip("distributed")
    from test_sweep_cluster import Cluster

    plan = plan_rough_ground(walker3, sigma=[0.005], strategy=["none"], trials=4, cap=100,
                             mesh=4, terrain_samples=4)
    mesh = [{"computed": False, "reason": "not asked", "sigmas": []}]
    local = run_rough_ground(plan, workers=1, meshes=mesh)
    cluster = Cluster(tmp_path, workers=1)
    try:
        remote = run_rough_ground(plan, scheduler=cluster.address, meshes=mesh)
    finally:
        cluster.stop()
    assert remote.executor["kind"] == "dask"
    assert _strip(remote) == _strip(local), cluster.logs()


# ----------------------------------------------------------------------- the command
@pytest.mark.slow
def test_command_on_walker5_writes_every_output_and_resumes(tmp_path, cli, monkeypatch):
    """From a folder other than the robot's, on tests/data/walker5 with its thrust gait: the
    JSON, mfpt.csv (one row per strategy and sigma), trials.csv, the trial records and the
    figure; the same command again computes nothing and writes the same document."""
    monkeypatch.chdir(tmp_path)
    robot, gait = DATA / "walker5.yaml", DATA / "walker5_thrust.yaml"
    args = ["rough-ground", str(robot), str(gait), "--sigma", "0.004", "--strategy",
            "none,constant:-10", "--trials", "4", "--cap", "40", "--mesh", "4",
            "--terrain-samples", "4", "--workers", "1", "--out", "out", "-q"]
    res = cli(*args)
    assert res.exit_code == 0, res.output
    out = tmp_path / "out"
    doc = json.loads((out / "rough_ground.json").read_text())
    assert [s["label"] for s in doc["strategies"]] == ["none", "constant:-10"]
    assert (out / "mfpt.png").is_file() and (out / "mfpt.pdf").is_file()
    assert len(list((out / "trials").glob("*.json"))) == 8
    rows = (out / "mfpt.csv").read_text().strip().splitlines()
    assert len([r for r in rows if not r.startswith("#")]) == 3  # header + 2 rows
    for s in doc["strategies"]:
        row = s["sigmas"][0]
        assert row["monte_carlo"]["trials"] == 4
        assert row["agreement"] in ("agree", "disagree", "not compared")
        assert s["mesh"]["computed"] and s["mesh"]["output_error_at_impact"] >= 0
    assert doc["headline"]["text"]
    again = cli(*args, "--formats", "csv")  # the figure, checked above, not drawn again
    assert again.exit_code == 0, again.output
    doc2 = json.loads((out / "rough_ground.json").read_text())
    assert doc2["counts"]["skipped"] == 8 and doc2["counts"]["computed"] == 0
    assert doc2["strategies"] == doc["strategies"]


@pytest.mark.parametrize("args, message", [
    (["--sigma", "-0.001"], "option --sigma:"),
    (["--sigma", "nan"], "option --sigma:"),
    (["--distribution", "cauchy"], "option --distribution:"),
    (["--strategy", "hover"], "option --strategy: unknown strategy 'hover'"),
    (["--mesh", "5"], "option --mesh: must be even"),
    (["--cap", "0"], "option --cap:"),
    (["--slope", "1.6"], "option --slope:"),
    (["--slope", "nan"], "option --slope:"),
    (["--slope", "-1.5708"], "option --slope:"),
])
def test_bad_input_is_one_line_exit_two_and_writes_nothing(tmp_path, cli, monkeypatch, args,
                                                           message):
    monkeypatch.chdir(tmp_path)
    res = cli("rough-ground", str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"),
              "--sigma", "0.004", "--trials", "2", *args, "--out", "bad", "-q")
    assert res.exit_code == 2, res.output
    lines = [ln for ln in res.output.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1 and message in lines[0], res.output
    assert "Traceback" not in res.output
    assert not (tmp_path / "bad").exists()
