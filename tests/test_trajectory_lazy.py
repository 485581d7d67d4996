"""The sampled time histories of a run are computed when first read (full_order.Trajectory):
the call and the document do not sample; reading gives exactly what sampling at once gives,
for both methods; the row count is known before."""

from __future__ import annotations

import numpy as np
import pytest

import thrustwalk_cli as tw
from thrustwalk_cli.simulation import full_order


@pytest.mark.parametrize("method", ["compiled", "scipy"])
def test_samples_are_taken_when_read_and_equal_eager_sampling(walker3, method, monkeypatch):
    calls = []
    eager = full_order._trajectory
    monkeypatch.setattr(full_order, "_trajectory", lambda *a: calls.append(1) or eager(*a))
    res = tw.simulate(walker3, steps=3, thrust_model="ideal", thrust=[0, -10],
                      start="nominal", method=method, samples=25)
    doc = res.document()
    assert calls == []  # neither the call nor its document sampled
    assert doc["trajectory_file"] == "trajectory.csv"
    for oc in res.outcomes:
        tr = oc.full.trajectory
        assert tr and tr.rows == 3 * 25
        cl, segs, per = tr._args
        ref = eager(cl, segs, per)  # sampled at once, independently of the mapping
        got = dict(tr)
        assert sorted(got) == sorted(ref) and got["t"].size == tr.rows
        for key in ref:
            np.testing.assert_array_equal(got[key], ref[key])
    assert len(calls) == 2  # once per run, when read
    dict(res.outcomes[0].full.trajectory)
    assert len(calls) == 2  # kept


def test_no_segment_is_an_empty_trajectory(walker3):
    res = tw.simulate(walker3, steps=1, thrust_model="ideal", thrust=[0], start="nominal")
    cl = res.outcomes[0].full.sim
    tr = full_order.Trajectory(cl, [], 25)
    assert not tr and tr.rows == 0 and len(tr) == 0 and dict(tr) == {}
