"""The README's Python blocks run as written (on a short simulated recording saved as recording.npz)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def python_blocks() -> list[str]:
    return re.findall(r"```python\n(.*?)```", README.read_text(), flags=re.S)


def test_readme_has_python_blocks():
    assert len(python_blocks()) >= 3


@pytest.mark.slow
def test_readme_python_blocks_run(tmp_path, monkeypatch, capsys):
    from cvstereo.io import write_recording
    from cvstereo.simulate import simulate_preset

    write_recording(tmp_path / "recording.npz", simulate_preset("1arm-100cm", seconds=0.6, seed=1))
    monkeypatch.chdir(tmp_path)
    namespace: dict = {}
    for i, block in enumerate(python_blocks()):
        try:
            exec(compile(block, f"README.md python block {i + 1}", "exec"), namespace)
        except Exception as exc:  # the failing block, named
            pytest.fail(f"README python block {i + 1} failed: {type(exc).__name__}: {exc}\n{block}")
    # The streaming loop keeps every packet's matches: they equal match() over the whole recording.
    from calibration_free import match

    whole = match(namespace["rec"], method="event-time", variant="shared", threshold=0.8)
    np.testing.assert_array_equal(namespace["matches"], whole.matches)
