"""Every command's JSON on the bundled robots and gaits equals its golden document
(tests/golden/, made by `make golden`; see tests/golden_cases.py): a change meant to move no
number moves none. Numbers agree to 1e-7 relative (plus 1e-9 absolute), so that another CPU's
last digits pass; THRUSTWALK_GOLDEN_EXACT=1 demands every number bit for bit (a change of
layout is checked so). Strings, booleans, keys and list lengths always agree exactly. The
design-gait cases are an optimiser's end point, which follows the BLAS's rounding: they agree
to 1e-3 with the solver's path (iterations, evaluations, the certificate of its last line
search) left out, and bit for bit in the exact mode."""

from __future__ import annotations

import json
import os

import pytest
from golden_cases import CASES, GOLDEN, LOOSE, REPO, differences, run_case

EXACT = os.environ.get("THRUSTWALK_GOLDEN_EXACT") == "1"


@pytest.mark.slow
@pytest.mark.parametrize("name, args, doc", CASES, ids=[c[0] for c in CASES])
def test_command_document_equals_its_golden_document(name, args, doc, cli, tmp_path,
                                                     monkeypatch):
    path = GOLDEN / f"{name}.json"
    assert path.is_file(), f"no golden document {path.name}: run `make golden`"
    monkeypatch.chdir(REPO)
    got = run_case(args, doc, tmp_path / name, lambda argv: cli(*argv).exit_code)
    want = json.loads(path.read_text())
    if EXACT:
        diff = differences(got, want)
    elif name in LOOSE:
        tol, skip = LOOSE[name]
        diff = differences(got, want, rtol=tol, atol=tol, skip=skip)
    else:
        diff = differences(got, want, rtol=1e-7, atol=1e-9)
    assert not diff, f"{name}: {len(diff)} differences, first: " + "; ".join(diff[:10])


def test_sentences_compare_their_numbers_loosely_and_their_words_exactly():
    """Outside exact mode a verdict's sentence may differ in rounding noise (two methods'
    difference printed as 8.9e-09 on one machine, 9e-09 on another), not in a word or in a
    number that means something."""
    from golden_cases import differences

    base = "largest difference 8.9e-09; multiplier 7 (outputs), against 1e-06 (scaled)"
    assert differences(base.replace("8.9e-09", "9e-09"), base, rtol=1e-7, atol=1e-9) == []
    for other in (base.replace("7", "6"), base.replace("outputs", "inputs"),
                  base.replace("1e-06", "1e-05"), base + " more"):
        assert differences(other, base, rtol=1e-7, atol=1e-9)
    assert differences(base.replace("8.9e-09", "9e-09"), base)  # exact mode: every digit
    assert differences("thruster q1", "thruster q2", rtol=1e-7, atol=1e-9)  # a name's digit
