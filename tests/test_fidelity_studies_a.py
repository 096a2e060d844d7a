"""Issue 35, Westwick & Perreault, Xu & Hollerbach and the apparatus study: the subject's values are
recordings (never in the headline), each published number and claim is checked once, the unstated damping
ratio makes X7 conditional, the paper's arithmetic is checked where it is arithmetic, and every note's
placeholder names a check that exists."""
from __future__ import annotations

import re

import pytest

from jointbench.benchmarks.config import load_study
from jointbench.benchmarks.studies.westwick2012 import protocol as W
from jointbench.benchmarks.studies.xu1998 import protocol as X

STUDIES = ("westwick2012", "xu1998", "apparatus")


@pytest.fixture(scope="module")
def checks():
    return {s: {c.id: c for c in load_study(s).checks} for s in STUDIES}


# ------------------------------------------------------------------------------ Westwick & Perreault
def test_the_single_subjects_values_are_recordings(checks):
    w = checks["westwick2012"]
    subject = ["W4-coherence-high", "W5-50Hz", "W5-100Hz", "W5-250Hz", "W5-500Hz", "W7-B"]
    assert all(w[i].evidence == "recording" for i in subject)
    # Table I's SDs are under Not reproduced, and Sec. V-B's 98.84 +- 0.10 is the 500 Hz row, checked once
    assert not [i for i in w if i.startswith("W5-sd") or i == "W5-overall"]
    assert [c.id for c in w.values() if c.published == "98.84 +- 0.10"] == ["W5-500Hz"]
    assert any("standard deviations" in n.item for n in load_study("westwick2012").not_reproduced)


def test_rate_invariance_is_the_one_table_i_claim_in_the_headline(checks):
    w = checks["westwick2012"]
    table1 = [c for c in w.values() if c.target == "Table I" and c.evidence == "reproduction"]
    assert [c.id for c in table1] == ["W5-rate-invariance"]
    c = table1[0]
    assert c.select["metric"] == "vaf_parametric_irf_range" and (c.low, c.high) == (0, 0.10)
    assert "1.25 times the Nyquist rate" in c.source
    # 50 Hz is 1.25 times the Nyquist rate of the 20 Hz band limit (reading R19), Table I's lowest rate
    params = load_study("westwick2012").parts["table1"].params
    assert min(params["fs"]) / (2 * 20) == 1.25


def test_rate_invariance_metrics():
    r = W.rate_invariance({500.0: 99.0, 250.0: 98.9, 100.0: 99.05, 50.0: 98.0}, 20.0)
    assert r["vaf_parametric_irf_range"] == pytest.approx(1.05)
    assert r["residual_ratio_lowest_rate"] == pytest.approx(2.0 / 1.0)
    assert r["lowest_rate_over_nyquist"] == pytest.approx(1.25)


# ------------------------------------------------------------------------------- Xu & Hollerbach
def test_output_vaf_sentence_is_one_check_over_every_frequency_tested(checks):
    x = checks["xu1998"]
    x3 = [c for c in x.values() if c.id.startswith("X3")]
    assert [c.id for c in x3] == ["X3-output"]
    c = x3[0]
    assert c.domain is None and "condition" not in c.select and c.aggregate == "min"
    assert c.evidence == "reproduction"


def test_x7_depends_on_the_unstated_damping_ratio(checks):
    x7 = [c for c in checks["xu1998"].values() if c.id.startswith("X7")]
    # issue 35: one check of the sentence over both conditions (zeta 0.1 is the readings table's, not a 2nd check)
    assert [c.id for c in x7] == ["X7-K-lowest-vafv"]
    assert all(c.evidence == "conditional" and c.readings == ("R3",) and "condition" not in c.select for c in x7)


def test_the_ratio_six_point_four_is_the_papers_arithmetic(checks):
    c = checks["xu1998"]["X9-ratio-6.4"]
    assert c.evidence == "conditional" and c.readings == ("R22",) and c.low <= 6.4 <= c.high
    r = X.filter_ratios(3.2, 0.5)
    assert r["cutoff_over_variation"] == pytest.approx(6.4)
    assert r["variation_over_cutoff"] == pytest.approx(0.15625)        # as printed: not 6.4
    fsewls = load_study("xu1998").parts["arithmetic"].estimators["fsewls"]
    assert str(fsewls["svf_cutoff"]).startswith("3.2")


def test_eight_times_rationale_is_not_checked_and_says_why():
    items = [n for n in load_study("xu1998").not_reproduced if "eight times" in n.item]
    assert len(items) == 1 and "Not arithmetic on the paper's own numbers" in items[0].reason


# ----------------------------------------------------------------------------------------- apparatus
def test_reasonable_estimate_is_checked_once(checks):
    a3 = [c for c in checks["apparatus"].values() if c.id.startswith("A3")]
    assert [c.id for c in a3] == ["A3-reasonable"]
    assert a3[0].domain == {"segment_s": 2} and "segment_s" not in a3[0].select


# ---------------------------------------------------------------------------------------------- notes
_PLACEHOLDER = re.compile(r"\{([^{}:]+)(?::[^{}]*)?\}")


@pytest.mark.parametrize("study", STUDIES)
def test_every_note_placeholder_names_a_check(study, checks):
    ids = set(checks[study])
    for c in checks[study].values():
        for text in (c.if_missed, c.if_missed_below, c.if_missed_above, c.cause):
            for name in _PLACEHOLDER.findall(text or ""):
                ref = name.removesuffix(".published")
                assert ref in ("value", "published") or ref in ids, (c.id, name)
