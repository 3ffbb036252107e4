"""Pictures and videos of recordings and matches: the thesis' figures, drawn from our data.

The plots need the ``viz`` extra (matplotlib: ``pip install 'cvstereo[viz]'``), imported when a plot is made;
:func:`write_video` needs the ``video`` extra (PyAV). Times shown count from the recording's origin
(``Recording.origin_us``). Every plot takes data and returns a :class:`matplotlib.figure.Figure`:

===============================  ================================================================  ===========
function                         shows                                                             thesis
===============================  ================================================================  ===========
:func:`plot_event_frames`        one window's events of both cameras, ON blue, OFF orange          fig. 3.2
:func:`plot_filtered_frames`     Gaussian-filtered signed frames, threshold contour, thresholded   fig. 3.3
:func:`plot_dynamic_frames`      the decaying dynamic frames of both cameras at an instant         fig. 3.5
:func:`plot_disparity_over_time` every match against time, median per window, ground truth         figs. 4.4/5
:func:`plot_disparity_map`       colour-coded disparity at the anchor pixels per window            figs. 4.3/6
:func:`plot_error_histogram`     signed error against ground truth, MAE and bad1                   --
===============================  ================================================================  ===========

>>> from cvstereo.viz import plot_event_frames, save_figure      # doctest: +SKIP
>>> save_figure(plot_event_frames(recording), "events.png")       # doctest: +SKIP
"""

from cvstereo.viz._images import busiest_window, colorize, depth_from_meta, event_frame_rgb
from cvstereo.viz.disparity_plots import plot_disparity_map, plot_disparity_over_time, plot_error_histogram
from cvstereo.viz.frame_plots import plot_dynamic_frames, plot_event_frames, plot_filtered_frames
from cvstereo.viz.mpl import save_figure
from cvstereo.viz.video import write_video

__all__ = ["busiest_window", "colorize", "depth_from_meta", "event_frame_rgb", "plot_disparity_map",
           "plot_disparity_over_time", "plot_dynamic_frames", "plot_error_histogram", "plot_event_frames",
           "plot_filtered_frames", "save_figure", "write_video"]
