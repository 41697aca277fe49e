"""How bad a walk's faults are (runtime/walk_checks.py: WalkReport.severity_by_kind) and when one
walk counts as worse than another (adds_faults): the refinement by motion refuses a walk that
adds a kind of fault or makes one of the start's worse by more than WORSE_BY."""
import pytest

from minifilm.runtime.walk_checks import WORSE_BY, WalkReport, adds_faults


def test_severities_are_the_distances_past_each_limit():
    bad = WalkReport(steps_per_s=0.9, toe_on_floor=0.4, hips=0.70, path_mean=3.0, clip_steps_per_s=1.6, clip_hips=0.90)
    s = bad.severity_by_kind()
    assert set(s) == {"steps", "floor", "hips", "path"}
    assert s["steps"] == pytest.approx(0.75 * 1.6 - 0.9)          # below 75 % of the clip's 1.6 steps/s
    assert s["floor"] == pytest.approx(0.9 - 0.4)                 # 90 % of frames asked, 40 % had
    assert s["hips"] == pytest.approx(0.20 - 0.09)                # 20 cm off, 10 % of 0.90 m allowed
    assert s["path"] == pytest.approx(3.0 - 1.0)
    fast = WalkReport(steps_per_s=2.5, toe_on_floor=0.95, hips=0.9, path_mean=0.1, clip_steps_per_s=1.6, clip_hips=0.9)
    assert fast.severity_by_kind() == {"steps": pytest.approx(2.5 - 1.25 * 1.6)}
    still = WalkReport(steps_per_s=0.1, toe_on_floor=0.95, hips=0.9, path_mean=0.1)      # no clip to compare with
    assert still.severity_by_kind() == {"steps": pytest.approx(0.5 - 0.1)}
    ok = WalkReport(steps_per_s=1.6, toe_on_floor=0.95, hips=0.9, path_mean=0.1, clip_steps_per_s=1.6, clip_hips=0.9)
    assert ok.severity_by_kind() == {}


def test_a_walk_is_worse_when_it_adds_a_kind_or_worsens_one_past_the_margin():
    start = {"floor": 0.3}
    assert not adds_faults({}, start)
    assert not adds_faults({"floor": 0.3 + WORSE_BY["floor"] * 0.9}, start)
    assert adds_faults({"floor": 0.3 + WORSE_BY["floor"] * 1.1}, start)
    assert adds_faults({"floor": 0.1, "path": 0.01}, start)                 # a kind the start has not
    assert not adds_faults({"path"}, {"path"}) and adds_faults({"path"}, set())     # kinds alone: severity 0
