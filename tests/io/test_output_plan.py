"""The output plan (cvstereo.io.output_plan) and the staging it shares with atomic_path, from the library side."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import pytest

from cvstereo.io.atomic import atomic_path, write_text_atomic
from cvstereo.io.output_plan import ANY_FILE, FIGURE, MATCHES_FILE, OutputPlan
from cvstereo.io.paths import OutputIsInputError
from tests._hostile import leftovers, null_device


def test_outputs_appear_only_when_the_block_ends(tmp_path):
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    plan = OutputPlan()
    plan.write(a, ANY_FILE)
    plan.write(b, ANY_FILE)
    with plan:
        write_text_atomic(a, "one")
        assert not a.exists() and len(leftovers(tmp_path)) == 2  # both reserved, neither published
        write_text_atomic(b, "two")
    assert (a.read_text(), b.read_text()) == ("one", "two") and not leftovers(tmp_path)


def test_an_exception_publishes_nothing_and_removes_the_folders_it_made(tmp_path):
    plan = OutputPlan()
    files = plan.write_folder(tmp_path / "new" / "figs", ["x.png", "sub/y.png"], FIGURE)
    with pytest.raises(RuntimeError, match="drawing failed"), plan:
        write_text_atomic(files[0], "x")
        raise RuntimeError("drawing failed")
    assert list(tmp_path.iterdir()) == []


def test_a_declared_output_never_written_is_not_published(tmp_path):
    (tmp_path / "keep.png").write_text("old")
    plan = OutputPlan()
    plan.write(tmp_path / "keep.png", FIGURE)
    plan.write(tmp_path / "new.png", FIGURE)
    with plan:
        write_text_atomic(tmp_path / "new.png", "new")
    assert (tmp_path / "keep.png").read_text() == "old" and (tmp_path / "new.png").read_text() == "new"
    assert not leftovers(tmp_path)


def test_files_the_plan_does_not_hold_are_written_at_once(tmp_path):
    """Caches written during a planned command's work (the demo's simulated recordings) are not its outputs."""
    plan = OutputPlan()
    plan.write(tmp_path / "out.txt", ANY_FILE)
    with plan:
        write_text_atomic(tmp_path / "cache.txt", "cached")
        assert (tmp_path / "cache.txt").read_text() == "cached"
        write_text_atomic(tmp_path / "out.txt", "out")


@pytest.mark.parametrize(("name", "ok"), [("m.npz", True), ("m", True), ("M.NPZ", True), ("m.ply", False),
                                          ("m.npz.bak", False)])
def test_an_output_name_says_its_kind_or_nothing(tmp_path, name, ok):
    plan = OutputPlan()
    plan.write(tmp_path / name, MATCHES_FILE, option="-o")
    if ok:
        plan.check()
        return
    with pytest.raises(ValueError, match=rf"-o .*{name}: this writes a matches file.*\.npz"):
        plan.check()


def test_one_character_device_takes_two_outputs_a_file_does_not(tmp_path):
    null_device(tmp_path / "null")
    plan = OutputPlan()
    plan.write(tmp_path / "null", ANY_FILE)
    plan.write(tmp_path / "null", ANY_FILE, option="--other")
    with plan:
        write_text_atomic(tmp_path / "null", "a")
        write_text_atomic(tmp_path / "null", "b")
    twice = OutputPlan()
    twice.write(tmp_path / "f.txt", ANY_FILE)
    twice.write(tmp_path / "sub" / ".." / "f.txt", ANY_FILE, option="--other")
    with pytest.raises(OutputIsInputError, match="the same file"):
        twice.check()


def test_a_missing_input_is_named_with_what_it_is(tmp_path):
    plan = OutputPlan()
    plan.read(tmp_path / "model.json", what="depth-model file (write one first)")
    with pytest.raises(FileNotFoundError, match=r"model.json: no such depth-model file \(write one first\)"):
        plan.check()


def test_a_full_disk_is_said_with_the_users_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(OSError, match=r"^out.txt: cannot write it: No space left on device$") as info:
        with atomic_path("out.txt") as tmp:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert info.value.errno == errno.ENOSPC and not Path(tmp).exists() and not leftovers(tmp_path)


def test_an_error_naming_another_file_is_left_alone(tmp_path):
    missing = str(tmp_path / "input.npz")
    with pytest.raises(FileNotFoundError) as info, atomic_path(tmp_path / "out.txt"):
        open(missing, "rb")
    assert info.value.filename == missing
