"""Small DSEC- and MVSEC-layout HDF5 files written with h5py itself (not with cvstereo), for the reader tests."""

from __future__ import annotations

import numpy as np


def write_dsec_events(path, events: np.ndarray, *, t_offset: int = 0, compress: bool = True) -> None:
    """A DSEC ``events.h5``: /events/{x,y,t,p} relative to /t_offset, and /ms_to_idx, as DSEC ships them."""
    import h5py
    import hdf5plugin

    t = events["t"] - t_offset
    assert t.size == 0 or (t.min() >= 0 and t.max() < 2**32)
    # ms_to_idx[k] = index of the first event with t >= 1000 k (DSEC's definition), up to the last event's ms.
    last_ms = int(t[-1] // 1000) if t.size else 0
    ms_to_idx = np.searchsorted(t, np.arange(last_ms + 2) * 1000, side="left").astype(np.uint64)
    kw = hdf5plugin.Blosc(cname="zstd") if compress else {}
    with h5py.File(path, "w") as f:
        g = f.create_group("events")
        g.create_dataset("x", data=events["x"].astype(np.uint16), **kw)
        g.create_dataset("y", data=events["y"].astype(np.uint16), **kw)
        g.create_dataset("t", data=t.astype(np.uint32), **kw)
        g.create_dataset("p", data=events["p"].astype(np.uint8), **kw)
        f.create_dataset("t_offset", data=np.int64(t_offset))
        f.create_dataset("ms_to_idx", data=ms_to_idx)


def write_mvsec_events(path, left: np.ndarray, right: np.ndarray) -> None:
    """An MVSEC data file: /davis/{left,right}/events as (N, 4) float64 x, y, t (s), p (-1/+1)."""
    import h5py

    with h5py.File(path, "w") as f:
        for name, ev in (("left", left), ("right", right)):
            rows = np.column_stack([ev["x"], ev["y"], ev["t"] / 1e6, np.where(ev["p"] == 1, 1.0, -1.0)])
            f.create_dataset(f"davis/{name}/events", data=rows.astype(np.float64))


def write_dsec_pair(folder, recording, *, t_offset: int) -> tuple:
    """A recording as DSEC ships a sequence: ``folder/events/{left,right}/events.h5``, each camera's times moved
    by ``t_offset`` (microseconds of the day, as DSEC's) and stored relative to it. Returns the two paths."""
    from pathlib import Path

    paths = []
    for cam in ("left", "right"):
        ev = getattr(recording, cam).copy()
        ev["t"] += t_offset
        path = Path(folder) / "events" / cam / "events.h5"
        path.parent.mkdir(parents=True, exist_ok=True)
        write_dsec_events(path, ev, t_offset=t_offset)
        paths.append(path)
    return tuple(paths)
