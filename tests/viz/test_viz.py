"""The pictures show the right data: rendered colours at known pixels, plotted data equal to the input."""

from __future__ import annotations

import sys

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

from cvstereo import viz  # noqa: E402
from cvstereo.errors import MissingExtraError  # noqa: E402
from cvstereo.geometry.depth import DepthModel  # noqa: E402
from cvstereo.model.events import make_events  # noqa: E402
from cvstereo.model.matches import MatchResult, make_matches  # noqa: E402
from cvstereo.model.recording import Recording  # noqa: E402
from cvstereo.viz._images import CONTEXT_RGB, match_window_slice, pixel_mean  # noqa: E402

#: A small sensor, so that each sensor pixel covers many screen pixels and colours can be read back exactly.
RES = (16, 12)
W = 40_000

#: The colour-blind-safe event colours (Okabe-Ito): ON sky blue, OFF orange, both white.
ON_C, OFF_C, BLACK, BOTH_C = (86, 180, 233), (230, 159, 0), (0, 0, 0), (255, 255, 255)


def _render(fig) -> np.ndarray:
    """The figure drawn with Agg, as an (H, W, 3) uint8 RGB array."""
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def _color_at(img: np.ndarray, ax, x: float, y: float) -> tuple[int, ...]:
    """Rendered colour at data coordinates (x, y) of ``ax``."""
    dx, dy = ax.transData.transform((x, y))
    return tuple(int(v) for v in img[round(img.shape[0] - dy), round(dx)])


def _close(c1, c2, tol: int = 2) -> bool:
    return bool(np.all(np.abs(np.subtract(c1, c2, dtype=int)) <= tol))


@pytest.fixture
def rec() -> Recording:
    """Events in the window [0, 40 ms): left ON at (3, 2), OFF at (5, 7), both at (9, 4); right ON at (1, 2).

    One later left event (t = 50 ms, ON at (12, 10)) lies outside the first window. Truth: 2 px at (3, 2),
    NaN (noise) elsewhere on the left, 2 px on the right.
    """
    left = make_events([100, 200, 300, 400, 50_000], [3, 5, 9, 9, 12], [2, 7, 4, 4, 10], [1, 0, 1, 0, 1])
    right = make_events([150, 50_100], [1, 10], [2, 10], [1, 1])
    nan = np.nan
    return Recording(left, right, [2.0, nan, nan, nan, 2.0], [2.0, 2.0], resolution=RES)


@pytest.fixture
def window_result() -> MatchResult:
    """Window-anchored matches (frame matcher style): window [0, 40 ms) stamped 40 ms, [40, 80) stamped 80 ms."""
    m = make_matches([W, W, 2 * W], [3, 9, 12], [2, 4, 10], [0, 0, 0], [0, 0, 0], [2.5, 8.0, 5.0])
    return MatchResult(m, {"method": "frame", "variant": "shared", "params": {}, "anchor": "window",
                           "window_us": W})


def test_event_frame_rgb_colours(rec):
    img = viz.event_frame_rgb(rec.left[:4], resolution=RES)
    assert img.shape == (12, 16, 3)
    assert tuple(img[2, 3]) == ON_C and tuple(img[7, 5]) == OFF_C and tuple(img[4, 9]) == BOTH_C
    assert tuple(img[0, 0]) == BLACK
    assert np.count_nonzero(img.any(axis=2)) == 3


def test_event_frames_picture_colours(rec):
    fig = viz.plot_event_frames(rec, 0, window_us=W)
    left_ax, right_ax = fig.axes[:2]
    img = _render(fig)
    assert _color_at(img, left_ax, 3, 2) == ON_C
    assert _color_at(img, left_ax, 5, 7) == OFF_C
    assert _color_at(img, left_ax, 9, 4) == BOTH_C
    assert _color_at(img, left_ax, 12, 10) == BLACK  # t = 50 ms: outside the window
    assert _color_at(img, right_ax, 1, 2) == ON_C
    assert _color_at(img, right_ax, 3, 2) == BLACK
    assert "left" in left_ax.get_title() and "right" in right_ax.get_title()
    assert left_ax.get_xlabel() == "x (px)"


def test_event_frames_default_is_busiest_window(rec):
    assert viz.busiest_window(rec, W) == 0
    fig = viz.plot_event_frames(rec)
    # The window stays on the absolute clock ([0, 40 ms)); times count from the first event, at 100 us.
    assert "[-0.1 ms, 39.9 ms)" in fig.get_suptitle() and "t = 0 at 100 µs" in fig.get_suptitle()


def test_filtered_frames_data_and_threshold(rng):
    from cvstereo.frames.accumulate import gaussian_filter, signed_frame

    # Ten ON events at one pixel: filtered centre 10 * 0.1621 > 1.2; a lone OFF event stays below.
    left = make_events(np.arange(11) * 10, [6] * 10 + [12], [5] * 10 + [2], [1] * 10 + [0])
    right = make_events(np.arange(10) * 10, [4] * 10, [5] * 10, [1] * 10)
    r = Recording(left, right, resolution=RES)
    fig = viz.plot_filtered_frames(r, 0, window_us=W, threshold=1.2)
    images = [ax.images[0].get_array() for ax in fig.axes[:4]]
    expected = gaussian_filter(signed_frame(left, resolution=RES))
    np.testing.assert_allclose(np.ma.filled(images[0], np.nan), expected, rtol=1e-6)
    thresholded = images[2]
    assert not np.ma.getmaskarray(thresholded)[5, 6] and np.isnan(np.ma.filled(thresholded, np.nan)[2, 12])
    assert fig.axes[0].collections, "the threshold contour is drawn on the filtered frame"


def test_dynamic_frames_agree_with_reference():
    from cvstereo.matchers._shared.reference_frames import DynamicFrames

    left = make_events([0, 1000, 2000, 700_000], [4, 4, 8, 2], [5, 5, 6, 2], [1, 1, 0, 1])
    right = make_events([500], [3], [5], [1])
    r = Recording(left, right, resolution=RES)
    t = 3000
    fig = viz.plot_dynamic_frames(r, t)
    ref = DynamicFrames(resolution=RES)
    for e in left[:3]:
        ref.add_event(t=int(e["t"]), x=int(e["x"]), y=int(e["y"]), p=int(e["p"]))
    ref.advance(t)
    np.testing.assert_allclose(fig.axes[0].images[0].get_array(), ref.values()[0], rtol=1e-12)
    assert fig.axes[1].images[0].get_array()[5, 3] > 0  # the right camera's ON event
    assert "3 ms" in fig.get_suptitle()


def test_dynamic_frames_separate_polarity_rows(rec):
    from cvstereo.frames.dynamic import DynamicFrameParams

    fig = viz.plot_dynamic_frames(rec, 1000, params=DynamicFrameParams(polarity="separate"))
    titles = [ax.get_title() for ax in fig.axes[:4]]
    assert "OFF" in titles[0] and "ON" in titles[2]


def test_disparity_over_time_plots_the_matches(rec, window_result):
    fig = viz.plot_disparity_over_time(rec, window_result, depth=DepthModel(a=16.5, c=0.0))
    ax = fig.axes[0]
    t, d = ax.lines[0].get_data()
    # Times count from the recording's first event (100 us).
    np.testing.assert_allclose(t, (window_result.matches["t"] - 100) / 1e6)
    np.testing.assert_array_equal(d, window_result.matches["disparity"])
    # Median of matches per window, at the window centres: [0, 40) holds 2.5 and 8.0, [40, 80) holds 5.0.
    mt, md = ax.lines[1].get_data()
    np.testing.assert_allclose(mt, [0.0199, 0.0599])
    np.testing.assert_allclose(md, [5.25, 5.0])
    # Ground truth: median of the left events' finite truth per window (2 px in both).
    _tt, td = ax.lines[2].get_data()
    np.testing.assert_allclose(td, [2.0, 2.0])
    assert ax.get_ylabel() == "disparity (px)"
    assert ax.get_xlabel() == "time (s; t = 0 at 100 µs on the recording's clock)"
    secondary = [c for c in ax.child_axes if c.get_ylabel() == "distance (m)"]
    assert secondary, "a metres axis is added when a DepthModel is given"


def test_disparity_over_time_without_truth_or_matches(rec):
    bare = Recording(rec.left, rec.right, resolution=RES)
    empty = MatchResult(make_matches([], [], [], [], [], []), {"anchor": "event", "window_us": 0})
    fig = viz.plot_disparity_over_time(bare, empty)
    assert fig.axes[0].lines[0].get_data()[0].size == 0


def _colour_of(d: float, vmin: float = 0.0, vmax: float = 10.0) -> tuple[int, ...]:
    """The colour the video gives disparity d: the plots must show the same."""
    return tuple(int(v) for v in viz.colorize(np.array([[d]]), vmin, vmax)[0, 0])


def test_disparity_map_colours_through_the_colormap(rec, window_result):
    fig = viz.plot_disparity_map(rec, window_result, W, vmin=0.0, vmax=10.0)
    axes = fig.axes
    # Columns: left events, right events, disparity (left), truth (left); then the colour bar.
    assert axes[2].get_title() == "disparity (left), 2 matches" and "truth" in axes[3].get_title()
    img = _render(fig)
    for x, y, d in ((3, 2, 2.5), (9, 4, 8.0)):
        assert _close(_color_at(img, axes[2], x, y), _colour_of(d))
    assert _color_at(img, axes[2], 12, 10) == BLACK  # the 80 ms match belongs to the next window
    assert _close(_color_at(img, axes[3], 3, 2), _colour_of(2.0))
    assert _color_at(img, axes[3], 5, 7) == CONTEXT_RGB  # noise: an event without truth, shown grey
    assert _color_at(img, axes[3], 0, 0) == BLACK  # no event
    assert fig.axes[-1].get_ylabel() == "disparity (px)"


def test_disparity_map_default_windows_and_event_anchors(rec):
    m = make_matches([100, 50_000], [3, 12], [2, 10], [1, 1], [0, 0], [2.0, 2.0])
    result = MatchResult(m, {"method": "event-time", "variant": "shared", "params": {}, "anchor": "event",
                             "window_us": 0})
    fig = viz.plot_disparity_map(rec, result, n_windows=2, depth=DepthModel(a=16.5))
    maps = [ax for ax in fig.axes if ax.get_title().startswith("disparity")]
    assert len(maps) == 2
    assert [int(np.isfinite(ax.images[-1].get_array()).sum()) for ax in maps] == [1, 1]


def test_disparity_map_needs_matches(rec):
    empty = MatchResult(make_matches([], [], [], [], [], []), {"anchor": "event", "window_us": 0})
    with pytest.raises(ValueError, match="no matches"):
        viz.plot_disparity_map(rec, empty)


def test_error_histogram_counts_and_title(rec, window_result):
    fig = viz.plot_error_histogram(rec, window_result)
    ax = fig.axes[0]
    heights = [p.get_height() for p in ax.patches if p.get_width() == 0.5]
    # Matches with truth: (3, 2) in [0, 40) -> error +0.5 and (12, 10) in [40, 80) -> +3.0; (9, 4) is noise.
    assert sum(heights) == 2
    title = ax.get_title()
    assert "MAE 1.75 px" in title and "bad1 (|error| > 1 px) 50.0%" in title and "false matches 33.3%" in title


def test_error_histogram_needs_truth(rec, window_result):
    with pytest.raises(ValueError, match="ground truth"):
        viz.plot_error_histogram(Recording(rec.left, rec.right, resolution=RES), window_result)


def test_match_window_slice_by_anchor():
    m = make_matches([0, 39_999, 40_000, 40_001], 0, 0, 0, 0, 1.0)
    assert match_window_slice(m, 0, W, anchor="event") == slice(0, 2)
    assert match_window_slice(m, 0, W, anchor="window") == slice(1, 3)


def test_pixel_mean_ignores_nan():
    img = pixel_mean(np.array([1, 1, 0]), np.array([0, 0, 0]), np.array([1.0, 3.0, np.nan]), resolution=(2, 1))
    np.testing.assert_array_equal(np.isnan(img), [[True, False]])
    assert img[0, 1] == 2.0


def test_depth_from_meta():
    assert viz.depth_from_meta({}) is None
    m = viz.depth_from_meta({"rig": {"focal_px": 165.0, "baseline_m": 0.1, "axis_offset_px": 3.0}})
    assert m == DepthModel(a=16.5, c=3.0)
    assert viz.depth_from_meta({"depth": {"a": 10.0, "c": 1.0}}) == DepthModel(10.0, 1.0)


def test_save_figure_is_atomic(rec, tmp_path):
    out = tmp_path / "events.png"
    viz.save_figure(viz.plot_event_frames(rec, 0), out)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    bad = tmp_path / "events.unknown-format"
    with pytest.raises(ValueError):
        viz.save_figure(viz.plot_event_frames(rec, 0), bad)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["events.png"]


def test_missing_matplotlib_names_the_extra(rec, monkeypatch):
    monkeypatch.setitem(sys.modules, "matplotlib.pyplot", None)
    with pytest.raises(MissingExtraError, match=r"cvstereo\[viz\]"):
        viz.plot_event_frames(rec, 0)


def _read_video(path):
    """The frames of a video, RGB, decoded by PyAV."""
    import av

    with av.open(str(path)) as container:
        return [f.to_ndarray(format="rgb24") for f in container.decode(video=0)]


def test_video_frames_size_and_colours(rec, window_result, tmp_path):
    from cvstereo.viz.video import _Layout

    # Sensor pixels 12 video pixels wide: H.264's lossy blocks bleed the colours of smaller ones into their
    # neighbours by more than the tolerance.
    scale = 12
    out = tmp_path / "rec.mp4"
    n = viz.write_video(rec, out, window_result, scale=scale, vmin=0.0, vmax=10.0, depth=DepthModel(a=16.5))
    frames = _read_video(out)
    # Events from 100 us to 50.1 ms: windows [0, 40) and [40, 80).
    assert n == len(frames) == 2
    layout = _Layout(RES, scale, n_disparity=1)
    assert frames[0].shape == (layout.size[1], layout.size[0], 3)
    # Centre of sensor pixel (x, y) of panel i, in video pixels.
    def at(i, x, y):
        px, py = layout.panel_origin(i)
        return frames[0][py + scale * y + scale // 2, px + scale * x + scale // 2].astype(int)
    assert _close(at(0, 3, 2), ON_C, tol=40) and _close(at(0, 5, 7), OFF_C, tol=40)
    assert _close(at(1, 1, 2), ON_C, tol=40)
    assert _close(at(2, 9, 4), _colour_of(8.0), tol=40)
    assert _close(at(2, 0, 0), BLACK, tol=40)
    assert _close(at(2, 5, 7), CONTEXT_RGB, tol=40)  # an event without a match


def test_video_without_matches_and_seconds(rec, tmp_path):
    out = tmp_path / "events.mp4"
    assert viz.write_video(rec, out, seconds=0.04, scale=2) == 1
    assert len(_read_video(out)) == 1


def test_video_errors_leave_no_file(rec, tmp_path, monkeypatch):
    with pytest.raises(ValueError, match=r"\.mp4"):
        viz.write_video(rec, tmp_path / "a.avi")

    import av

    def refuse(*args, **kwargs):
        raise OSError("no encoder")

    viz.video.video_codec()  # probed before the refusal
    monkeypatch.setattr(av, "open", refuse)
    with pytest.raises(OSError, match="cannot open a video encoder"):
        viz.write_video(rec, tmp_path / "b.mp4")
    assert list(tmp_path.iterdir()) == []
