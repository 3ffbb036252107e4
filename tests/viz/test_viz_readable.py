"""Pictures a person can read: colour-blind-safe polarity colours shared by every figure, disparity colours
scaled to the scene, titles that name the recording, paper widths, log histograms, the video's codec."""

from __future__ import annotations

import numpy as np
import pytest

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")

from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402

from cvstereo import viz  # noqa: E402
from cvstereo.cli import main  # noqa: E402
from cvstereo.io import write_matches, write_recording  # noqa: E402
from cvstereo.model.events import make_events  # noqa: E402
from cvstereo.model.matches import MatchResult, make_matches  # noqa: E402
from cvstereo.model.recording import Recording  # noqa: E402
from cvstereo.viz._images import disparity_range  # noqa: E402
from cvstereo.viz.mpl import SIGNED_CMAP, cmap_with_background, figure_title, set_paper_width  # noqa: E402

RES = (16, 12)


def _hue(rgb) -> float:
    import colorsys

    return colorsys.rgb_to_hsv(*(c / 255 for c in rgb[:3]))[0] * 360


def test_on_and_off_share_their_hue_in_event_frames_and_signed_frames():
    """ON is blue and OFF orange in the event frames and at both ends of the signed scale."""
    events = make_events([0, 0], [1, 2], [0, 0], [1, 0])
    on_rgb, off_rgb = viz.event_frame_rgb(events, resolution=(3, 1))[0, 1:3]
    cmap = cmap_with_background(SIGNED_CMAP)
    strong_on = np.array(cmap(1.0)) * 255
    strong_off = np.array(cmap(0.0)) * 255
    assert 190 <= _hue(on_rgb) <= 215 and 190 <= _hue(strong_on) <= 215  # blue
    assert 25 <= _hue(off_rgb) <= 45 and 15 <= _hue(strong_off) <= 45  # orange / vermillion
    assert min(np.array(cmap(0.5))[:3]) * 255 > 250  # zero is white
    # Red and green, the pair red-green colour-blind readers confuse, are no longer the polarity colours.
    assert tuple(on_rgb) != (0, 255, 0) and tuple(off_rgb) != (255, 0, 0)


def _rendered(fig) -> np.ndarray:
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3]


def test_filtered_frames_draw_on_blue_and_off_orange():
    """Ten ON events at one pixel and ten OFF at another: the filtered picture shows them blue and orange."""
    t = np.arange(20) * 10
    ev = make_events(t, [4] * 10 + [11] * 10, [5] * 20, [1] * 10 + [0] * 10)
    rec = Recording(ev, ev.copy(), resolution=RES)
    fig = viz.plot_filtered_frames(rec, 0, window_us=40_000)
    img = _rendered(fig)
    ax = fig.axes[0]
    h = img.shape[0]
    (xa, ya), (xb, yb) = ax.transData.transform([(4, 5), (11, 5)])
    on_px, off_px = img[round(h - ya), round(xa)], img[round(h - yb), round(xb)]
    assert on_px[2] > on_px[0] + 60, f"ON pixel {on_px} is not blue"
    assert off_px[0] > off_px[2] + 60, f"OFF pixel {off_px} is not orange"


@pytest.mark.parametrize(("values", "reference", "expected"), [
    # 29-30 px, one depth: the scale spans 28-31 (margin 1 px), not 0-45 as before.
    ([29.0] * 50 + [30.0] * 50, None, (28.0, 31.0)),
    # The scene's truth sets the range; a wrong match at 3 px and one at 60 px do not stretch it.
    ([3.0, 29.0, 30.0, 60.0], [29.0] * 50 + [30.0] * 50, (28.0, 31.0)),
    # 10..20 px uniformly: 2nd..98th percentile 10.2..19.8, margin 15 % of 9.6 = 1.44.
    (list(np.linspace(10, 20, 1001)), None, (8.76, 21.24)),
    # Never below 0 when no value is.
    ([0.0] * 50 + [1.0] * 50, None, (0.0, 2.0)),
    ([np.nan], None, (0.0, 1.0)),
])
def test_disparity_range_follows_the_data(values, reference, expected):
    ref = None if reference is None else [np.array(reference)]
    assert disparity_range(np.array(values), reference=ref) == pytest.approx(expected, abs=1e-6)


def _scene():
    """Left-anchored matches at 29-30 px over truth of 29-30 px, plus one wild match at 5 px."""
    rng = np.random.default_rng(0)
    n = 400
    t = np.sort(rng.integers(0, 40_000, n))
    x, y = rng.integers(0, 16, n), rng.integers(0, 12, n)
    truth = np.where(x < 8, 29.0, 30.0)
    left = make_events(t, x, y, rng.integers(0, 2, n))
    rec = Recording(left, left.copy(), truth, truth, resolution=RES)
    disp = truth.copy()
    disp[0] = 5.0
    m = make_matches(t, x, y, left["p"], 0, disp)
    return rec, MatchResult(m, {"method": "event-area", "variant": "gaussian", "params": {}, "anchor": "event",
                                "window_us": 0, "anchor_cameras": [0], "input": ["/data/Fan_disp8.dat"]})


def _map_norm(fig):
    """The colour scale of the disparity panels (the only images holding scalar data, not RGB)."""
    return next(im.norm for ax in fig.axes for im in ax.get_images() if im.get_array().ndim == 2)


def test_disparity_map_scale_follows_the_truth_and_obeys_vmin_vmax():
    rec, result = _scene()
    fig = viz.plot_disparity_map(rec, result, [40_000])
    norm = _map_norm(fig)
    assert (norm.vmin, norm.vmax) == pytest.approx((28.0, 31.0))
    fig = viz.plot_disparity_map(rec, result, [40_000], vmin=0, vmax=45)
    norm = _map_norm(fig)
    assert (norm.vmin, norm.vmax) == (0, 45)


def test_titles_name_a_real_file():
    rec, result = _scene()
    assert figure_title(result.meta, rec.meta) == "event-area (gaussian) on Fan_disp8.dat"
    assert figure_title(result.meta, {"preset": "1arm-50cm"}) == "event-area (gaussian) on 1arm-50cm"
    rec.meta["name"] = "logo.dat"
    assert "of logo.dat" in viz.plot_event_frames(rec, 0)._suptitle.get_text()


def test_error_histogram_log_axis():
    rec, result = _scene()
    assert viz.plot_error_histogram(rec, result).axes[0].get_yscale() == "linear"
    assert viz.plot_error_histogram(rec, result, log=True).axes[0].get_yscale() == "log"


def test_paper_width_keeps_aspect_and_readable_text():
    rec, result = _scene()
    fig = viz.plot_disparity_map(rec, result, [40_000])
    w, h = fig.get_size_inches()
    set_paper_width(fig, 3.5)
    assert fig.get_size_inches() == pytest.approx((3.5, h * 3.5 / w))
    from matplotlib.text import Text

    sizes = [t.get_fontsize() for t in fig.findobj(Text) if t.get_text()]
    assert min(sizes) >= 6.5
    with pytest.raises(ValueError, match=r"outside 1\.\.50 inches"):
        set_paper_width(fig, 0.2)


@pytest.fixture()
def files(tmp_path):
    rec, result = _scene()
    rec_path, m_path = tmp_path / "rec.npz", tmp_path / "m.npz"
    write_recording(rec_path, rec)
    write_matches(m_path, result.matches, result.meta)
    return rec_path, m_path


def test_cli_plot_column_width_vmin_and_log(files, tmp_path, capsys):
    import cv2

    rec_path, m_path = files
    out = tmp_path / "map.png"
    assert main(["plot", "disparity-map", str(rec_path), str(m_path), "-o", str(out), "--column", "--dpi", "100",
                 "--vmin", "0", "--vmax", "40"]) == 0
    assert cv2.imread(str(out)).shape[1] == 350  # 3.5 in at 100 dpi
    out = tmp_path / "hist.png"
    assert main(["plot", "error-hist", str(rec_path), str(m_path), "-o", str(out), "--log"]) == 0
    assert out.read_bytes()[:4] == b"\x89PNG"


def test_video_says_its_codec(files, tmp_path, capsys):
    from cvstereo.viz.video import CODEC_NAMES, CODECS, video_codec

    rec_path, m_path = files
    assert video_codec() in CODECS
    assert main(["video", str(rec_path), str(m_path), "-o", str(tmp_path / "v.mp4")]) == 0
    assert CODEC_NAMES[video_codec()] in capsys.readouterr().out
