"""Parameter sweeps over many recordings on Dask distributed: what ``cvstereo sweep`` runs.

A sweep is a grid of *cells*, one per recording x method x variant x combination of parameter values; a
cell is one :func:`match` plus :func:`cvstereo.evaluation.metrics.evaluate`. Cells run on a Dask cluster: a
``LocalCluster`` with one single-threaded worker process per core by default (nothing to set up), or an
existing cluster given by its scheduler address. Workers get the recording's *path*, never its events, and
stream it themselves, so nothing large travels through the scheduler.

Every finished cell is written at once to ``OUT/cells/KEY.json``; the key hashes the recording's content,
the method, variant and parameters, and the package's source files (the version number does not change
when the code does). A sweep started again with the same output folder therefore only runs the cells that
are missing: an interrupted sweep resumes, and a changed matcher recomputes; a cell file that is not a whole
row of its cell (cut short, edited, copied) is recomputed too. A cell that fails (a corrupt file, a bug) is
stored with its error and never stops the others; what cannot work is refused before any cell runs: a
recording that is no regular file, a grid value the matcher refuses (:meth:`Grid.configs`). The table is
assembled in grid order, so the same grid gives the same table whatever the number of workers (timing
columns aside: :data:`TIMING_COLUMNS`).

>>> grid = Grid(methods=("event-area",), params=(("threshold", (1.5, 2.5)),))
>>> [c.label for c in grid.cells(["a.npz"])]  # doctest: +SKIP
['event-area/gaussian [threshold=1.5] on a.npz', 'event-area/gaussian [threshold=2.5] on a.npz']
"""

from cvstereo.sweep.cells import FIGURE_COLUMNS, TIMING_COLUMNS
from cvstereo.sweep.engine import (
    SweepResult,
    cell_key,
    check_output_folder,
    file_digest,
    recording_digest,
    run_cell,
    run_sweep,
    source_digest,
)
from cvstereo.sweep.grid import Cell, Grid
from cvstereo.sweep.grid_file import read_grid_file
from cvstereo.sweep.recordings import resolve_recordings
from cvstereo.sweep.report import LOWER_IS_BETTER, check_figure, summary_markdown, write_table

__all__ = ["FIGURE_COLUMNS", "LOWER_IS_BETTER", "TIMING_COLUMNS", "Cell", "Grid", "SweepResult", "cell_key",
           "check_figure", "check_output_folder", "file_digest", "read_grid_file", "recording_digest",
           "resolve_recordings", "run_cell", "run_sweep", "source_digest", "summary_markdown", "write_table"]
