"""Every code block of docs/ runs as written, on a short simulated recording saved as recording.npz."""

from __future__ import annotations

import shutil

import pytest

from tests._docs_blocks import DOCS, RUN_LANGUAGES, SHOWN_LANGUAGES, blocks, command_lines, doc_pages

#: The recording every page finds in its folder (docs/index.md says how to make the same file).
RECORDING = {"preset": "1arm-50cm", "seconds": 0.5, "seed": 1}


@pytest.fixture(scope="session")
def docs_recording(tmp_path_factory):
    from cvstereo.io import write_recording
    from cvstereo.simulate import simulate_preset

    path = tmp_path_factory.mktemp("docs") / "recording.npz"
    write_recording(path, simulate_preset(RECORDING["preset"], seconds=RECORDING["seconds"],
                                          seed=RECORDING["seed"]))
    return path


def test_index_names_the_recording_the_blocks_run_on():
    """The page that tells readers how the examples run gives the same recording as the fixture."""
    index = (DOCS / "index.md").read_text()
    assert (f"cvstereo simulate --preset {RECORDING['preset']} --seconds {RECORDING['seconds']} "
            f"--seed {RECORDING['seed']} -o recording.npz") in index


def test_every_block_is_run_or_skipped_with_a_reason():
    """No block escapes the runner: each is python or bash (run unless skipped with a reason) or text, and every
    bash block that runs holds cvstereo commands only."""
    found = [b for page in doc_pages() for b in blocks(page)]
    fence_lines = sum(line.startswith("```") for page in doc_pages() for line in page.read_text().splitlines())
    assert fence_lines == 2 * len(found) > 0  # the parser missed no block
    for block in found:
        assert block.lang in RUN_LANGUAGES + SHOWN_LANGUAGES, f"{block.where()}: fence {block.lang!r}"
        assert block.skip is None or block.skip, f"{block.where()}: a skip needs its reason"
        if block.lang == "bash" and block.skip is None:
            assert command_lines(block.code), f"{block.where()}: an empty bash block"


def test_command_lines_join_continuations_and_refuse_other_programs():
    assert command_lines("cvstereo match a.npz \\\n    -m sgbm -o m.npz   # comment\n\n") == [
        ["match", "a.npz", "-m", "sgbm", "-o", "m.npz"]]
    with pytest.raises(ValueError, match="not a cvstereo command"):
        command_lines("pip install cvstereo\n")


@pytest.mark.slow
@pytest.mark.parametrize("page", [p.relative_to(DOCS).as_posix() for p in doc_pages()])
def test_page_blocks_run(page, docs_recording, tmp_path, monkeypatch, capsys):
    from tests._docs_blocks import run_page

    shutil.copy(docs_recording, tmp_path / "recording.npz")
    monkeypatch.chdir(tmp_path)
    run_page(DOCS / page, capsys)
