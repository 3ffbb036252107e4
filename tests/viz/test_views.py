"""Issue 26 items 4 and 6 at the command line: times from the recording's origin, colour-blind-safe disparity
colours, visible legend swatches, browser-playable videos that fit a screen, ``--rerun`` files rerun opens."""

from __future__ import annotations

import json
import re
import sys
from collections import Counter

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

from cvstereo.cli import main  # noqa: E402
from cvstereo.io import write_matches, write_recording  # noqa: E402
from cvstereo.model.events import make_events  # noqa: E402
from cvstereo.model.matches import make_matches  # noqa: E402
from cvstereo.model.recording import Recording  # noqa: E402

#: A DV-style clock: microseconds since 1970 (the issue's titles read "1.7e+12 ms"), and the done-criterion's 1.7e12 us.
CLOCKS = (1_700_000_000_123_456, 1_700_000_000_000)
RES = (640, 480)
SPAN_US, DISPARITY = 2_200_000, 6.0

#: Colour-vision-deficiency simulation (Machado, Oliveira & Fernandes 2009, severity 1.0), on linear RGB.
DEUTERANOPIA = np.array([[0.367322, 0.860646, -0.227968], [0.280085, 0.672501, 0.047413],
                         [-0.011820, 0.042940, 0.968881]])
PROTANOPIA = np.array([[0.152286, 1.052583, -0.204868], [0.114503, 0.786281, 0.099216],
                       [-0.003882, -0.048116, 1.051998]])
NORMAL = np.eye(3)


def _lstar(rgb, matrix=NORMAL) -> np.ndarray:
    """CIE L* of sRGB colours as seen through ``matrix`` (written out here, not taken from cvstereo)."""
    c = np.asarray(rgb, np.float64) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    lin = np.clip(lin @ matrix.T, 0.0, 1.0)
    y = lin @ np.array([0.2126, 0.7152, 0.0722])
    return np.where(y > 0.008856, 116 * np.cbrt(y) - 16, 903.3 * y)


def _scene(t0: int, meta: dict | None = None):
    """A bar at disparity 6 px on a 640 x 480 sensor for 2.2 s of clock ``t0``, and matches of most left events."""
    rng = np.random.default_rng(1)
    n = 6000
    t = np.sort(rng.integers(0, SPAN_US, n)) + t0
    x, y, p = rng.integers(200, 300, n), rng.integers(100, 300, n), rng.integers(0, 2, n)
    truth = np.full(n, DISPARITY)
    rec = Recording(make_events(t, x, y, p), make_events(t, x - 6, y, p), truth, truth, resolution=RES,
                    meta={"rig": {"focal_px": 500.0, "baseline_m": 0.1, "axis_offset_px": 0.0}, **(meta or {})})
    keep = rng.random(n) < 0.5
    m = make_matches(t[keep], x[keep], y[keep], p[keep], 0, DISPARITY + rng.normal(0, 0.5, keep.sum()))
    return rec, m


def _write(folder, t0: int):
    rec, m = _scene(t0)
    write_recording(folder / "rec.npz", rec)
    write_matches(folder / "m.npz", m, {"method": "event-time", "variant": "shared", "params": {},
                                        "anchor": "event", "window_us": 0})
    return folder / "rec.npz", folder / "m.npz", rec, m


@pytest.fixture(scope="module", params=CLOCKS, ids=["dv-clock", "1.7e12"])
def files(request, tmp_path_factory):
    """The scene on either clock: for the tests of times."""
    return _write(tmp_path_factory.mktemp("views"), request.param)


@pytest.fixture(scope="module")
def dv_files(tmp_path_factory):
    """The scene on the DV clock: for the tests of colours, video and rerun."""
    return _write(tmp_path_factory.mktemp("views-dv"), CLOCKS[0])


def _svg_texts(path) -> list[str]:
    """The texts of an SVG matplotlib wrote (it keeps each as a comment beside its glyph paths)."""
    return re.findall(r"<!-- (.*?) -->", path.read_text())


def test_plot_events_times_from_origin_and_t_start_2000(files, tmp_path, capsys):
    rec_path, _, rec, _ = files
    out = tmp_path / "events.svg"
    assert main(["plot", "events", str(rec_path), "-o", str(out), "--t-start-ms", "2000"]) == 0
    texts = _svg_texts(out)
    origin = rec.t_start
    assert "Events in [2000 ms, 2040 ms) of rec.npz" in texts
    assert f"t = 0 at {origin} µs on the recording's clock" in texts
    assert not any("e+" in t for t in texts)
    # The window shown is [origin + 2 s, origin + 2.04 s) of the clock: its events counted here.
    t = rec.left["t"]
    n = int(np.count_nonzero((t >= origin + 2_000_000) & (t < origin + 2_040_000)))
    assert n > 0 and f"left camera (0): {n:,} events" in texts


def test_t_start_past_the_end_names_the_span_from_origin(files, tmp_path, capsys):
    rec_path, _, rec, _ = files
    assert main(["plot", "events", str(rec_path), "-o", str(tmp_path / "e.png"), "--t-start-ms", "5000"]) == 1
    err = capsys.readouterr().err
    last_ms = (rec.t_end - rec.t_start) / 1000
    assert err.count("\n") == 1 and f"between 0 ms and {last_ms:g} ms after its origin" in err
    assert not (tmp_path / "e.png").exists()


def test_disparity_map_titles_relative_short_and_counted(files, tmp_path, capsys):
    rec_path, m_path, rec, m = files
    out = tmp_path / "map.svg"
    assert main(["plot", "disparity-map", str(rec_path), str(m_path), "-o", str(out), "--t-start-ms", "1500",
                 "--windows", "2"]) == 0
    texts = _svg_texts(out)
    origin = rec.t_start
    for k in range(2):
        start = origin + 1_500_000 + k * 40_000
        n = int(np.count_nonzero((m["t"] >= start) & (m["t"] < start + 40_000)))
        assert f"left events, {1500 + 40 * k} ms + 40 ms" in texts
        assert f"disparity (left), {n} matches" in texts
    assert not any("e+" in t or re.search(r"\(\d+\)$", t) for t in texts)


def test_disparity_over_time_axis_counts_from_origin(files):
    from cvstereo import viz
    from cvstereo.model.matches import MatchResult

    _, _, rec, m = files
    fig = viz.plot_disparity_over_time(rec, MatchResult(m, {"anchor": "event", "window_us": 0}))
    t = fig.axes[0].lines[0].get_xdata()
    np.testing.assert_allclose(t, (m["t"] - rec.left["t"][0]) / 1e6)
    assert 0 <= t.min() and t.max() <= SPAN_US / 1e6


def test_info_shows_the_origin_once(files, capsys):
    rec_path, _, rec, _ = files
    assert main(["info", str(rec_path)]) == 0
    out = capsys.readouterr().out
    assert out.count(str(rec.t_start)) == 1 and f"t = 0 at {rec.t_start} us" in out


def test_stored_origin_counts_times_and_a_corrupt_one_is_refused(tmp_path, capsys):
    t0 = CLOCKS[0]
    rec, _ = _scene(t0, meta={"origin_us": t0 - 1_000_000})  # a part of a recording that began 1 s earlier
    write_recording(tmp_path / "part.npz", rec)
    out = tmp_path / "e.svg"
    assert main(["plot", "events", str(tmp_path / "part.npz"), "-o", str(out), "--t-start-ms", "3000"]) == 0
    assert "Events in [3000 ms, 3040 ms) of part.npz" in _svg_texts(out)
    bad = Recording(rec.left, rec.right, resolution=RES)
    write_recording(tmp_path / "bad.npz", bad)
    import json

    data = dict(np.load(tmp_path / "bad.npz"))
    data["meta"] = np.array(json.dumps({"origin_us": 1.5}))
    np.savez(tmp_path / "bad.npz", **data)
    assert main(["plot", "events", str(tmp_path / "bad.npz"), "-o", str(tmp_path / "x.png")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "origin_us" in err and "bad.npz" in err
    assert not (tmp_path / "x.png").exists()


# --- colours ---------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("matrix", [NORMAL, DEUTERANOPIA, PROTANOPIA], ids=["normal", "deuteranopia", "protanopia"])
def test_default_disparity_colours_keep_their_order_for_colour_blind_readers(matrix):
    from cvstereo.viz.colormaps import DISPARITY_CMAP, disparity_lut

    lut = disparity_lut(DISPARITY_CMAP)
    seen = _lstar(lut, matrix)
    # Every step from low to high disparity is lighter, as seen without red or green cones too.
    assert np.all(np.diff(seen[::8]) > 0.5)
    # The darkest colour stands out from black (no event) and from the grey of events without a match (L* 29).
    assert seen[0] >= 35


def test_the_order_check_tells_a_rainbow_apart():
    from cvstereo.viz.colormaps import disparity_lut

    # turbo (the old default) rises and falls in lightness: the same check fails on it.
    assert not np.all(np.diff(_lstar(disparity_lut("turbo"), DEUTERANOPIA)[::8]) > 0.5)


def test_legend_swatches_stand_out_from_the_figure(dv_files):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from cvstereo import viz

    _, _, rec, _ = dv_files
    fig = viz.plot_event_frames(rec)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    img = np.asarray(canvas.buffer_rgba())[..., :3]
    background = _lstar(np.array([255, 255, 255]))
    patches = fig.legends[0].get_patches()
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["ON", "OFF", "ON and OFF"]
    for patch in patches:
        box = patch.get_window_extent(canvas.get_renderer())
        x0, x1 = int(box.x0), int(np.ceil(box.x1))
        y0, y1 = img.shape[0] - int(np.ceil(box.y1)), img.shape[0] - int(box.y0)
        swatch = img[y0:y1 + 1, x0:x1 + 1].reshape(-1, 3)
        # Some of its pixels (edge or fill) differ clearly from the white figure.
        assert (background - _lstar(swatch)).max() > 20, patch.get_label()


def test_cmap_option(dv_files, tmp_path, capsys):
    rec_path, m_path, _, _ = dv_files
    assert main(["plot", "disparity-map", str(rec_path), str(m_path), "-o", str(tmp_path / "a.png"),
                 "--cmap", "magma", "--windows", "1", "--dpi", "40"]) == 0
    for argv in (["plot", "disparity-map", str(rec_path), str(m_path), "-o", str(tmp_path / "b.png")],
                 ["video", str(rec_path), str(m_path), "-o", str(tmp_path / "b.mp4")]):
        capsys.readouterr()
        assert main([*argv, "--cmap", "no-such-map"]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "--cmap 'no-such-map'" in err and "viridis" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png"]


# --- video ----------------------------------------------------------------------------------------------------


def _decode(path):
    import av

    with av.open(str(path)) as container:
        stream = container.streams.video[0]
        return stream.codec_context.name, [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]


def test_video_browser_codec_fits_1280_and_colour_bar_safe(dv_files, tmp_path, capsys):
    pytest.importorskip("av")
    from cvstereo.viz.video import _Layout, fit_scale

    rec_path, m_path, rec, _ = dv_files
    out = tmp_path / "v.mp4"
    assert main(["video", str(rec_path), str(m_path), "-o", str(out), "--seconds", "0.2"]) == 0
    assert "H.264" in capsys.readouterr().out
    codec, frames = _decode(out)
    assert codec == "h264"
    # Windows of the absolute 40 ms grid from the one holding the first event, for 0.2 s.
    first = rec.t_start - rec.t_start % 40_000
    assert len(frames) == len([k for k in range(first, first + 200_000, 40_000)])
    h, w, _ = frames[0].shape
    assert w <= 1280 and w % 2 == 0 and h % 2 == 0
    assert w > 1000  # the width is used, not a thumbnail
    # The colour bar, top (high disparity) to bottom: lighter to darker, also for colour-blind readers.
    layout = _Layout(RES, fit_scale(RES, 1), n_disparity=1)
    x = layout.colorbar_x + 6
    rows = np.linspace(layout.header + 4, layout.header + layout.ph - 4, 12).astype(int)
    bar = frames[0][rows, x]
    for matrix in (NORMAL, DEUTERANOPIA, PROTANOPIA):
        seen = _lstar(bar, matrix)
        assert np.all(np.diff(seen) < 0), seen
        assert seen[-1] >= 33  # the low end shows on black (codec noise allowed)


def test_video_max_width_and_scale(dv_files, tmp_path, capsys):
    pytest.importorskip("av")
    rec_path, _, _, _ = dv_files
    assert main(["video", str(rec_path), "-o", str(tmp_path / "a.mp4"), "--seconds", "0.04",
                 "--max-width", "640"]) == 0
    assert _decode(tmp_path / "a.mp4")[1][0].shape[1] <= 640
    with pytest.raises(SystemExit) as exc:  # a usage error
        main(["video", str(rec_path), "-o", str(tmp_path / "b.mp4"), "--seconds", "0.04", "--max-width", "640",
              "--scale", "1"])
    assert exc.value.code == 2 and "--max-width" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mp4"]


def test_video_without_pyav_names_the_extra(dv_files, tmp_path, monkeypatch, capsys):
    rec_path, _, _, _ = dv_files
    monkeypatch.setitem(sys.modules, "av", None)
    assert main(["video", str(rec_path), "-o", str(tmp_path / "v.mp4")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cvstereo[video]" in err
    assert list(tmp_path.iterdir()) == []


# --- rerun ----------------------------------------------------------------------------------------------------

EXPECTED = {"/cameras/left/events", "/cameras/right/events", "/cameras/left/disparity", "/cameras/left/depth",
            "/world/points"}


def _entities(path) -> set[str]:
    """Entity paths of an .rrd, read by rerun's own loader."""
    from rerun.chunk import RrdReader

    return {c.entity_path for c in RrdReader(str(path)).store().schema().component_columns()}


def test_video_rerun_file_opens_in_rerun(dv_files, tmp_path, capsys):
    pytest.importorskip("rerun")
    pytest.importorskip("av")
    rec_path, m_path, _, _ = dv_files
    out = tmp_path / "v.rrd"
    assert main(["video", str(rec_path), str(m_path), "-o", str(tmp_path / "v.mp4"), "--seconds", "0.1",
                 "--rerun", str(out)]) == 0
    assert EXPECTED <= _entities(out)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["v.mp4", "v.rrd"]


def test_match_rerun_file_opens_in_rerun(tmp_path, capsys):
    pytest.importorskip("rerun")
    rec, _ = _scene(CLOCKS[0])
    write_recording(tmp_path / "rec.npz", rec.slice_time(None, rec.t_start + 300_000))
    out = tmp_path / "m.rrd"
    assert main(["match", str(tmp_path / "rec.npz"), "-o", str(tmp_path / "m.npz"), "--rerun", str(out)]) == 0
    assert "-> " + str(out) in capsys.readouterr().out
    assert EXPECTED <= _entities(out)


def test_rerun_without_the_sdk_names_the_extra(dv_files, tmp_path, monkeypatch, capsys):
    rec_path, m_path, _, _ = dv_files
    monkeypatch.setitem(sys.modules, "rerun", None)
    assert main(["video", str(rec_path), str(m_path), "-o", str(tmp_path / "v.mp4"), "--rerun",
                 str(tmp_path / "v.rrd")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "cvstereo[rerun]" in err
    assert list(tmp_path.iterdir()) == []


def test_rerun_without_a_viewer_fails_before_any_work(dv_files, tmp_path, monkeypatch, capsys):
    rr = pytest.importorskip("rerun")
    rec_path, m_path, _, _ = dv_files

    def no_viewer(self, *args, **kwargs):
        raise RuntimeError("Failed to find Rerun Viewer executable in PATH. Install it with ...")

    def never(*args, **kwargs):
        raise AssertionError("the video was drawn although the viewer could not start")

    monkeypatch.setattr(rr.RecordingStream, "spawn", no_viewer)
    monkeypatch.setattr("cvstereo.viz.video.write_video", never)
    assert main(["video", str(rec_path), str(m_path), "-o", str(tmp_path / "v.mp4"), "--rerun"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "cannot start a rerun viewer (Failed to find Rerun Viewer executable in PATH)" in err
    assert "--rerun FILE.rrd" in err and list(tmp_path.iterdir()) == []


def test_live_rerun_file_holds_every_packet(tmp_path, capsys):
    """``live --simulate --rerun FILE``: rerun's own loader finds the live entities, one step per logged packet on
    the rig's clock (times rising, within the recording), every event of both cameras once, and 3D points of
    the matches."""
    pytest.importorskip("rerun")
    import pyarrow.compute as pc
    from rerun.chunk import RrdReader

    rng = np.random.default_rng(3)
    n, span_us = 4000, 400_000
    t = np.sort(rng.integers(0, span_us, n))
    x, y, p = rng.integers(8, 128, n), rng.integers(0, 128, n), rng.integers(0, 2, n)
    write_recording(tmp_path / "src.npz", Recording(make_events(t, x, y, p), make_events(t, x - 6, y, p)))
    out = tmp_path / "live.rrd"
    assert main(["live", "--simulate", str(tmp_path / "src.npz"), "-m", "event-time", "--rerun", str(out)]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    summary = json.loads(err[-1])["summary"]
    packets = int(next(line for line in err if line.endswith(f"packets -> {out}")).split()[0])
    rows, points, times = Counter(), Counter(), []
    for chunk in RrdReader(str(out)).store().stream():
        batch, path = chunk.to_record_batch(), chunk.entity_path
        names = batch.schema.names
        rows[path] += chunk.num_rows
        for name in ("Points2D:positions", "Points3D:positions"):
            if name in names:
                points[path] += pc.sum(pc.list_value_length(batch.column(names.index(name)))).as_py() or 0
        if path == "/cameras/left/events":
            times += [v / 1e9 for v in batch.column(names.index("time")).cast("int64").to_pylist()]
    live = {"/cameras/left/events", "/cameras/right/events", "/cameras/right/disparity", "/cameras/right/depth",
            "/world/points"}  # event-time anchors its matches on the right camera
    assert live <= set(rows) and {rows[e] for e in live} == {packets}
    # 0.4 s played at its own speed: the rig hands out a packet at least every few tens of ms.
    assert 5 <= packets <= n and len(times) == packets
    assert np.all(np.diff(sorted(times)) > 0) and t[0] / 1e6 < min(times) and max(times) <= span_us / 1e6 + 1
    assert points["/cameras/left/events"] == points["/cameras/right/events"] == n == summary["events_left"]
    assert 0 < points["/world/points"] <= summary["matches"]
    assert sorted(f.name for f in tmp_path.iterdir()) == ["live.rrd", "src.npz"]
