"""The rig check on several threads: the same findings as on one (its Fourier transforms run on ``threads``)."""

from __future__ import annotations

import dataclasses

import pytest
import scipy.fft

from cvstereo.rigcheck.check import check_rig
from cvstereo.rigcheck.prefix import PrefixRigCheck
from tests.rigcheck.test_rigcheck import with_rig_errors


@pytest.fixture(scope="module")
def arm_with_time_offset():
    """A 2-arm clip (no depth wobble) with the right camera 3 ms late and 2 rows off: the shift-velocity
    regression answers the time offset, so its transforms run."""
    from cvstereo.simulate import get_preset, simulate

    preset = get_preset("2arms-50cm")
    rec = simulate(dataclasses.replace(preset.scene, wobble_m=0.0), rig=preset.rig, seconds=2.0, seed=1)
    return with_rig_errors(rec, rows=2, time_us=3000)


def test_findings_are_the_same_on_one_and_two_threads(arm_with_time_offset, monkeypatch):
    workers = []
    rfft = scipy.fft.rfft

    def counting_rfft(*args, **kwargs):
        workers.append(scipy.fft.get_workers())
        return rfft(*args, **kwargs)

    monkeypatch.setattr(scipy.fft, "rfft", counting_rfft)
    one = check_rig(arm_with_time_offset, threads=1)
    two = check_rig(arm_with_time_offset, threads=2)
    assert one.settings["time_offset_method"] == "shift-velocity regression"
    assert set(workers) == {1, 2}  # each check ran its transforms on the threads it was given
    assert one.to_dict() == two.to_dict()
    assert abs(one.time_offset_us - 3000) <= 500 and round(one.row_offset) == round(two.row_offset)


def test_prefix_check_passes_its_threads_on(arm_with_time_offset, monkeypatch):
    seen = []
    import cvstereo.rigcheck.check as check_module

    real = check_module.check_rig

    def spy(*args, **kwargs):
        seen.append(kwargs.get("threads"))
        return real(*args, **kwargs)

    monkeypatch.setattr(check_module, "check_rig", spy)
    check = PrefixRigCheck(arm_with_time_offset.resolution, threads=2)
    for _ in check.stream(arm_with_time_offset.packets(40_000)):
        pass
    assert seen == [2] and check.report is not None


@pytest.mark.parametrize("threads", [0, 2.5, True, "2"])
def test_a_thread_count_that_is_no_whole_number_is_refused(arm_with_time_offset, threads):
    with pytest.raises(ValueError, match="threads"):
        check_rig(arm_with_time_offset, threads=threads)
