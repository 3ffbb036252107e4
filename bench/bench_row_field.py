"""Rows that differ across the image: what a per-pixel row correction would give, and can the rows be found per tile?

Suite v2's rigs have a roll, a focal mismatch and two different lenses besides a row offset, as real uncalibrated
rigs do; the rig check applies one row offset to the whole image. This measures, on one half of suite v2:

- the **true row field**: the rows to add to each right pixel's y to reach the left camera's row of its ray
  (:meth:`cvstereo.simulate.Rig.right_row_shift`), its span over the image, and how far the whole-image offset the
  prefix check applies leaves it (RMS over the pixels);
- **the oracle**: each method run on the recording as read (the default rig check) and on the recording with the
  right camera's rows moved by the true field, rounded (rig check off): bad2 and coverage of fused, SGBM and
  dv-semidense, and fused's bad2 at each peer's coverage (its most certain answers, as bench_fusedgen.py);
- **a prototype estimator**, not in the package: frame-area (adaptive) on the prefix span the rows by matching use,
  with the right camera moved by every second offset within +-8 rows of the row offset the check applies; its answers
  counted per tile (4 x 3), each tile's peak offset (parabola), a weighted least-squares fit of
  ``shift = a + b u + c v + e v (u^2 + v^2)`` (u, v from the image centre over half the width: a row offset, a
  roll, a focal mismatch, different lens distortion), tiles over 1.5 rows off refitted away twice; its RMS
  against the true field beside the constant's, and the answers with the fitted field over those with the
  constant (the only evidence a recording without truth would have).

Run: ``.venv/bin/python bench/bench_row_field.py [--half tune] [--only NAME,...] [-o bench/results]``. Writes
``row-field.md`` and ``row-field.json``. A measurement for the next step of issue 24, not a tuning script: it
changes no constant (the tuning half by default, through ``require_tuning``). Other modes:

- ``--fits``, ``--applied-fit``: the prototype's fits compared, and the chosen one applied (row-field-fits.md,
  row-field-applied.md);
- ``--estimator``: the package's estimator (:mod:`cvstereo.rigcheck.row_field`) on the tuning half and on 48 more
  tuning draws (:func:`extra_tuning_recordings`), where its constants were chosen (row-field-estimator.md);
- ``--package [--half eval]``: every method with ``match(row_field=True)`` beside the default
  (row-field-package-HALF.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_fused import most_certain

from cvstereo.evaluation.metrics import evaluate
from cvstereo.io.npz import read_recording_npz
from cvstereo.rigcheck.peaks import subsample_peak
from cvstereo.rigcheck.prefix import PrefixRigCheck
from cvstereo.rigcheck.row_field import MIN_GAIN, TILES, RowField, estimate_row_field
from cvstereo.rigcheck.rows_by_matching import matching_span, span_matches
from cvstereo.run import match
from cvstereo.simulate import Rig, require_tuning, suite_recordings

PEERS = ("sgbm", "dv-semidense")
#: The prototype estimator's reach and step in rows, least answers of a tile (its tiles: the package's).
REACH, STEP, MIN_ANSWERS = 8, 2, 20
#: Rig fields of a recording's meta that make its Rig.
RIG_FIELDS = ("baseline_m", "focal_px", "axis_offset_px", "vertical_offset_px", "distortion_k1", "roll_deg",
              "focal_ratio", "right_distortion_k1")


def true_shift(rec) -> np.ndarray:
    """The suite rig's true row field of ``rec``, (H, W)."""
    rig = Rig(resolution=tuple(rec.resolution), **{k: v for k, v in rec.meta["rig"].items() if k in RIG_FIELDS})
    return rig.right_row_shift()


def move_rows(events: np.ndarray, shift, height: int) -> tuple[np.ndarray, np.ndarray]:
    """``events`` with each row moved by ``shift`` (a number, or (H, W) at each event's pixel), rounded; those
    moved off the sensor dropped. Returns the moved events and which were kept."""
    at = shift[events["y"], events["x"]] if np.ndim(shift) else shift
    y = np.rint(events["y"] + at).astype(np.int64)
    keep = (y >= 0) & (y < height)
    moved = events[keep].copy()
    moved["y"] = y[keep]
    return moved, keep


def moved_rows(rec, shift: np.ndarray):
    """``rec`` with each right event's row moved by ``shift`` at its pixel (:func:`move_rows`)."""
    moved, keep = move_rows(rec.right, shift, rec.resolution[1])
    truth = None if rec.right_disparity is None else rec.right_disparity[keep]
    return dataclasses.replace(rec, right=moved, right_disparity=truth)


def applied_rows(rec) -> int | None:
    """The row offset the prefix check of ``match()`` applies to ``rec`` (its 40 ms packets; the check runs before
    the first one), None where it did not run."""
    check = PrefixRigCheck(rec.resolution)
    next(check.stream(rec.packets(40_000)))
    return None if check.report is None else int(check.describe()["applied"]["row_offset"])


def figures(rec, **kw) -> dict:
    """bad2 and coverage of fused (and its ranked result) and of the peers on ``rec``."""
    out = {}
    for peer in PEERS:
        f = evaluate(rec, match(rec, method=peer, **kw))
        out[peer] = {"coverage": f["coverage"], "bad2": f["bad2"]}
    res = match(rec, method="fused", max_uncertainty=1.0, **kw)
    unc = res.arrays["uncertainty"]
    f = evaluate(rec, res.matches[unc <= 0.5], res.meta)
    out["fused"] = {"coverage": f["coverage"], "bad2": f["bad2"]}
    for peer in PEERS:
        kept = most_certain(res.matches, unc, rec, res.meta, out[peer]["coverage"] or 0.0)
        out[f"fused@{peer}"] = evaluate(rec, kept, res.meta)["bad2"]
    return out


def _design(x, y, w):
    """The field's terms at columns ``x`` and rows ``y`` counted from the image centre."""
    u, v = (x - (w - 1) / 2) / (w / 2), y / (w / 2)
    return np.stack([np.ones_like(u), u, v, v * (u * u + v * v)], axis=-1)


def _answers(left, right, rec, end, shift) -> np.ndarray:
    """frame-area's matches on the span with the right rows moved by ``shift`` (a number or (H, W))."""
    moved = move_rows(right, shift, rec.resolution[1])[0]
    return span_matches(left, moved, resolution=rec.resolution, end=end)


def tile_peaks(rec, centre: int, reach: int = REACH) -> dict:
    """The package's answers per tile over row offsets ``centre - reach .. centre + reach`` (every second;
    :func:`cvstereo.rigcheck.row_field.estimate_row_field`), read with the prototype's rules: each tile's peak
    offset (parabola), its weight (answers at the peak times the profile's prominence) and its centre (x from the
    left, y from the image centre), for tiles with MIN_ANSWERS or more, wherever their peak lies."""
    w, h = rec.resolution
    counts = estimate_row_field(rec.left, rec.right, resolution=rec.resolution, centre=centre, reach=reach).counts
    offsets = np.arange(centre - reach, centre + reach + 1, STEP)
    peaks, weights, cx, cy = [], [], [], []
    for j in range(TILES[1]):
        for k in range(TILES[0]):
            prof = counts[:, j, k]
            b = int(np.argmax(prof))
            if prof[b] < MIN_ANSWERS:
                continue
            peaks.append(float(offsets[0]) + STEP * subsample_peak(prof, b))
            weights.append(prof[b] * (1 - np.median(prof) / prof[b]))
            cx.append((k + 0.5) * w / TILES[0])
            cy.append((j + 0.5) * h / TILES[1] - (h - 1) / 2)
    # Every answer falls in a tile (clipped), so an offset's tiles sum to its run's answers.
    answers = counts.sum(axis=(1, 2)).astype(int).tolist()
    end = matching_span(rec.left, rec.right, min_us=80_000, max_us=10_000_000, events=100_000)
    return {"peaks": np.array(peaks), "weights": np.array(weights), "x": np.array(cx), "y": np.array(cy),
            "end": end, "centre": centre, "answers": dict(zip(offsets.tolist(), answers, strict=True))}


def fit_field(tiles: dict, resolution, *, terms: int = 4, ridge: float = 0.0, clip: bool = False,
              gate: tuple[int, float] | None = None) -> tuple[np.ndarray | None, int]:
    """The prototype's fit: weighted least squares of the first ``terms`` terms over the tiles, tiles over 1.5 rows
    (or 2.5 median residuals) off dropped and refitted twice. Variants: ``ridge`` (the slope terms pulled towards 0
    by ``ridge`` times the tiles' total weight), ``clip`` (the field kept within the used tiles' peaks +-1 row: no
    extrapolation), ``gate`` = (least tiles used, largest weighted RMS residual, rows): None where it fails.
    Fewer tiles than terms: the centre. Returns the field (H, W) or None, and the tiles used."""
    w, h = resolution
    peaks, weights = tiles["peaks"], tiles["weights"]
    a = _design(tiles["x"], tiles["y"], w)[:, :terms]
    use = np.ones(peaks.size, bool)
    coef = np.array([float(tiles["centre"])] + [0.0] * (terms - 1))
    for _ in range(3):
        if use.sum() < terms:
            break
        sw = np.sqrt(weights[use])
        lhs, rhs = a[use] * sw[:, None], peaks[use] * sw
        if ridge:
            prior = np.sqrt(ridge * weights[use].sum()) * np.eye(terms)[1:]
            lhs, rhs = np.vstack([lhs, prior]), np.concatenate([rhs, np.zeros(terms - 1)])
        coef = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
        res = np.abs(a @ coef - peaks)
        use = res <= max(1.5, 2.5 * float(np.median(res[use])))
    if gate is not None:
        res = a @ coef - peaks
        spread = float(np.sqrt(np.average(res[use] ** 2, weights=weights[use]))) if use.any() else np.inf
        if use.sum() < gate[0] or spread > gate[1]:
            return None, int(use.sum())
    yy, xx = np.mgrid[0:h, 0:w].astype(float)
    field = _design(xx, yy - (h - 1) / 2, w)[..., :terms] @ coef
    if clip and use.any():
        field = np.clip(field, peaks[use].min() - 1, peaks[use].max() + 1)
    return field, int(use.sum())


#: The fits compared by ``--fits``: name -> fit_field's options.
FITS = {"plain": {}, "clip": {"clip": True}, "affine + clip": {"terms": 3, "clip": True},
        "ridge 0.1 + clip": {"ridge": 0.1, "clip": True},
        "affine + clip, gate 5 tiles / 0.7 rows": {"terms": 3, "clip": True, "gate": (5, 0.7)}}
#: How far ``--fits`` and ``--applied-fit`` search around the row offset the check applies.
FITS_REACH = 12


def fits_table(half: str) -> list[str]:
    """Every fit of FITS on every recording of ``half``: RMS against the true field beside the constant's."""
    rows = []
    for name, path in suite_recordings("generalization", half=half):
        if half == "tune":
            require_tuning(path)
        rec = read_recording_npz(path)
        offset = applied_rows(rec)
        shift = true_shift(rec)
        tiles = tile_peaks(rec, offset, FITS_REACH)
        rms = {"constant": float(np.sqrt(np.mean((shift - offset) ** 2)))}
        for fit, options in FITS.items():
            field = fit_field(tiles, rec.resolution, **options)[0]
            rms[fit] = rms["constant"] if field is None else float(np.sqrt(np.mean((field - shift) ** 2)))
        rows.append((name, rms))
        print(name, {k: round(v, 2) for k, v in rms.items()}, flush=True)
    lines = [f"## Fits of the prototype's tiles ({half} half, +-{FITS_REACH} rows around the check's row offset)", "",
             "RMS over the pixels against the true field, rows; a gated fit that fails keeps the constant.", "",
             "| recording | constant applied | " + " | ".join(FITS) + " |",
             "|---|---:|" + "---:|" * len(FITS)]
    lines += [f"| {name} | {r['constant']:.2f} | " + " | ".join(f"{r[f]:.2f}" for f in FITS) + " |" for name, r in rows]
    lines.append("| better / worse than the constant by 0.1+ rows | | " + " | ".join(
        f"{sum(r[f] < r['constant'] - 0.1 for _, r in rows)} / {sum(r[f] > r['constant'] + 0.1 for _, r in rows)}"
        for f in FITS) + " |")
    return lines


def estimate(rec, centre: int) -> dict:
    """The prototype on ``rec``: its fitted field, tiles, and the answers with it over those with the centre."""
    tiles = tile_peaks(rec, centre)
    field, used = fit_field(tiles, rec.resolution)
    end = tiles["end"]
    left, right = rec.left[rec.left["t"] < end], rec.right[rec.right["t"] < end]
    n_field = _answers(left, right, rec, end, field).size
    n_const = tiles["answers"][centre]  # the centre is on the offsets' grid (REACH is a multiple of STEP)
    return {"field": field, "tiles": int(tiles["peaks"].size), "used": used, "answers_ratio": n_field / max(n_const, 1)}


def one(name: str, path: Path, half: str) -> dict:
    if half == "tune":
        require_tuning(path)
    rec = read_recording_npz(path)
    shift = true_shift(rec)
    checked = applied_rows(rec)
    rows = checked or 0
    start = time.perf_counter()
    as_read = figures(rec)
    oracle = figures(moved_rows(rec, np.rint(shift)), rig_check=False)
    est = None if checked is None else estimate(rec, rows)
    row = {"name": name, "sensor": f"{rec.resolution[0]}x{rec.resolution[1]}",
           "field_min": float(shift.min()), "field_max": float(shift.max()), "applied_rows": rows,
           "constant_rms": float(np.sqrt(np.mean((shift - rows) ** 2))), "as_read": as_read, "oracle": oracle,
           "seconds": round(time.perf_counter() - start, 1)}
    if est is not None:
        row.update(estimate_rms=float(np.sqrt(np.mean((est["field"] - shift) ** 2))), tiles=est["tiles"],
                   tiles_used=est["used"], answers_ratio=est["answers_ratio"])
    return row


def _fused_cell(f: dict) -> str:
    return f"{f['fused']['bad2']:.3f} ({f['fused']['coverage']:.2f})"


def table(rows: list[dict]) -> list[str]:
    lines = ["| recording | true field rows | applied | RMS constant / prototype fit | fit: tiles used, answers "
             "ratio | fused default, as read -> oracle | fused @ sgbm vs sgbm, as read -> oracle | fused @ dv vs dv, "
             "as read -> oracle |", "|---|---|---:|---|---|---|---|---|"]
    for r in rows:
        a, o = r["as_read"], r["oracle"]
        cells = []
        for peer in PEERS:
            cells.append(f"{a[f'fused@{peer}']:.3f} vs {a[peer]['bad2']:.3f} -> {o[f'fused@{peer}']:.3f} vs "
                         f"{o[peer]['bad2']:.3f}")
        fitted = f"{r['estimate_rms']:.2f}" if "estimate_rms" in r else "-"
        fit = f"{r['constant_rms']:.2f} / {fitted}"
        used = f"{r['tiles_used']}/{r['tiles']}, {r['answers_ratio']:.3f}" if "tiles" in r else "-"
        lines.append(f"| {r['name']} | {r['field_min']:+.1f} .. {r['field_max']:+.1f} | {r['applied_rows']:+d} | "
                     f"{fit} | {used} | {_fused_cell(a)} -> {_fused_cell(o)} | " + " | ".join(cells) + " |")
    return lines


def beats(f: dict) -> bool:
    return all(f[f"fused@{p}"] < (f[p]["bad2"] if f[p]["coverage"] else 1.0) for p in PEERS)


#: The fit ``--applied-fit`` applies: of the fits in row-field-fits.md (tuning half) the one further from the truth
#: than the whole-image offset least often and by least (4 recordings, at most 0.54 rows).
APPLIED_FIT = "affine + clip, gate 5 tiles / 0.7 rows"


def applied_fit_table(half: str, output: Path) -> list[str]:
    """Each method on the recording with the right rows moved by APPLIED_FIT's field (the check's constant where
    its gate fails), beside the figures as read and with the oracle of ``output/row-field.json``."""
    before = {r["name"]: r for r in json.loads((output / "row-field.json").read_text())}
    rows = []
    for name, path in suite_recordings("generalization", half=half):
        if name not in before:
            continue
        if half == "tune":
            require_tuning(path)
        rec = read_recording_npz(path)
        tiles = tile_peaks(rec, applied_rows(rec), FITS_REACH)
        field = fit_field(tiles, rec.resolution, **FITS[APPLIED_FIT])[0]
        shift = true_shift(rec)
        if field is None:
            fitted, rms = before[name]["as_read"], before[name]["constant_rms"]
        else:
            fitted, rms = figures(moved_rows(rec, np.rint(field)), rig_check=False), \
                float(np.sqrt(np.mean((field - shift) ** 2)))
        rows.append({**before[name], "fitted": fitted, "fitted_rms": rms, "gated": field is None})
        print(name, "gate failed" if field is None else f"rms {rms:.2f}", _fused_cell(fitted), flush=True)
    lines = [f"## With the prototype's field applied ({APPLIED_FIT}; {half} half)", "",
             f"fused better than both peers at parity: as read {sum(beats(r['as_read']) for r in rows)}, fitted "
             f"{sum(beats(r['fitted']) for r in rows)}, oracle {sum(beats(r['oracle']) for r in rows)} of {len(rows)}.",
             "", "| recording | RMS constant / fitted | fused default: as read / fitted / oracle | SGBM bad2: as read "
             "/ fitted / oracle | dv-semidense bad2: as read / fitted / oracle |", "|---|---|---|---|---|"]
    for r in rows:
        fit_rms = "gate failed" if r["gated"] else f"{r['fitted_rms']:.2f}"
        peers = [" / ".join(f"{r[k][p]['bad2']:.3f}" for k in ("as_read", "fitted", "oracle")) for p in PEERS]
        lines.append(f"| {r['name']} | {r['constant_rms']:.2f} / {fit_rms} | "
                     + " / ".join(_fused_cell(r[k]) for k in ("as_read", "fitted", "oracle"))
                     + f" | {peers[0]} | {peers[1]} |")
    return lines


def package_row(name: str, path: Path, half: str) -> dict:
    """Each method with ``match()``'s default rig check and with ``row_field=True``; the field found (from the
    meta entry) against the true field."""
    if half == "tune":
        require_tuning(path)
    rec = read_recording_npz(path)
    shift = true_shift(rec)
    check = match(rec, method="frame-area", row_field=True).meta["rigcheck"]
    applied = check["applied"]
    found = check.get("row_field") or {}
    rms_constant = float(np.sqrt(np.mean((shift - applied["row_offset"]) ** 2)))
    if applied.get("row_field"):
        fitted = RowField.from_description(found, rec.resolution)
        rms_field = float(np.sqrt(np.mean((np.rint(fitted.rows()) - shift) ** 2)))
        with_field = figures(rec, row_field=True)
    else:
        rms_field, with_field = None, None
    as_read = figures(rec)
    return {"name": name, "applied_rows": applied["row_offset"], "field": found, "constant_rms": rms_constant,
            "field_rms": rms_field, "as_read": as_read, "with_field": with_field or as_read,
            "field_seconds": found.get("seconds"), "check_seconds": check["seconds"]}


def package_table(half: str) -> tuple[list[str], list[dict]]:
    """package_row over ``half``: the lines of row-field-package-HALF.md and its rows."""
    rows = []
    for name, path in suite_recordings("generalization", half=half):
        rows.append(package_row(name, path, half))
        r = rows[-1]
        field_rms = "none" if r["field_rms"] is None else f"{r['field_rms']:.2f}"
        print(f"{name:26s} rms {r['constant_rms']:.2f} -> {field_rms}  fused {_fused_cell(r['as_read'])} -> "
              f"{_fused_cell(r['with_field'])}", flush=True)
    applied = [r for r in rows if r["field_rms"] is not None]
    better = sum(r["field_rms"] < r["constant_rms"] - 0.1 for r in applied)
    worse = sum(r["field_rms"] > r["constant_rms"] + 0.1 for r in applied)
    lines = [f"## `match(row_field=True)` on the {half} half", "",
             f"A field was found and applied on {len(applied)} of {len(rows)} recordings: closer to the true field "
             f"than the whole-image offset (by 0.1+ rows RMS) on {better}, further on {worse}. fused better than both "
             f"peers at parity: default check {sum(beats(r['as_read']) for r in rows)}, with the field "
             f"{sum(beats(r['with_field']) for r in rows)} of {len(rows)}.", "",
             "| recording | RMS rows: offset / field | field rows, tiles used / told | search s (check s) | "
             "fused default: check / field | SGBM bad2: check / field | dv-semidense bad2: check / field | "
             "fused @ SGBM, @ dv: check / field |", "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        f = r["field"]
        fitted = f"{r['field_rms']:.2f}" if r["field_rms"] is not None else "none"
        told = f"{f['rows'][0]:+d} .. {f['rows'][1]:+d}, {f['tiles_used']}/{f['tiles']}" if "rows" in f else \
            f"-, 0/{f.get('tiles', 0)}"
        seconds = f"{r['field_seconds']:.2f} ({r['check_seconds']:.2f})" if r["field_seconds"] is not None else "-"
        peers = [" / ".join(f"{r[k][p]['bad2']:.3f}" for k in ("as_read", "with_field")) for p in PEERS]
        parity = " / ".join(", ".join(f"{r[k][f'fused@{p}']:.3f}" for p in PEERS) for k in ("as_read", "with_field"))
        lines.append(f"| {r['name']} | {r['constant_rms']:.2f} / {fitted} | {told} | {seconds} | "
                     f"{_fused_cell(r['as_read'])} / {_fused_cell(r['with_field'])} | {peers[0]} | {peers[1]} | "
                     f"{parity} |")
    return lines, rows


#: Seeds added to each tuning recording's for the extra tuning recordings (the halves' seeds are 1xxx and 2xxx).
EXTRA_SEED_SHIFTS = (2000, 3000)


def extra_tuning_recordings() -> list[tuple[str, Path]]:
    """Suite v2's tuning recordings drawn again with other seeds (EXTRA_SEED_SHIFTS): the same families, sensors
    and tuning photos, other scenes, sensors and rigs; generated once into the simulator's cache. Tuning data:
    their half is ``tune``, and the evaluation half's seeds and photos stay unseen."""
    import tomllib

    from cvstereo.io.npz import write_recording_npz
    from cvstereo.simulate.generalization import parse_family_suite
    from cvstereo.simulate.presets import default_cache_dir

    source = Path(__file__).resolve().parent.parent / "cvstereo/simulate/suites/generalization_v2.toml"
    data = tomllib.loads(source.read_text())
    data["recording"] = [{**e, "name": e["name"].replace("-tune-", f"-tunx{k}-"), "seed": e["seed"] + shift}
                         for e in data["recording"] if e["half"] == "tune"
                         for k, shift in enumerate(EXTRA_SEED_SHIFTS)]
    folder = default_cache_dir() / "row-field-extra"
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for rec in parse_family_suite(data, where="row-field extra").recordings:
        path = folder / f"{rec.name}-{rec.seed}.npz"
        if not path.exists():
            write_recording_npz(path, rec.simulate())
        out.append((rec.name, path))
    return out


def estimator_table() -> list[str]:
    """The package's estimator on the tuning half and the extra tuning recordings: the fit and the field applied
    (after the answers' check) against the true field, beside the whole-image offset."""
    rows = []
    for name, path in [*suite_recordings("generalization", half="tune"), *extra_tuning_recordings()]:
        require_tuning(path)
        rec = read_recording_npz(path)
        centre = applied_rows(rec)
        if centre is None:
            continue
        found = estimate_row_field(rec.left, rec.right, resolution=rec.resolution, centre=centre)
        shift = true_shift(rec)

        def rms(field, shift=shift, centre=centre):
            rows_applied = centre if field is None else np.rint(field.rows())
            return float(np.sqrt(np.mean((rows_applied - shift) ** 2)))

        gain = None if found.answers is None else found.answers / max(found.best_offset_answers, 1)
        rows.append((name, rms(None), rms(found.fitted), rms(found.field), gain))
        print(name, [round(v, 2) for v in rows[-1][1:4]], gain, flush=True)

    def tally(k):
        return (f"{sum(r[k] < r[1] - 0.1 for r in rows)} / {sum(r[k] > r[1] + 0.1 for r in rows)} "
                f"(worst {max(r[k] - r[1] for r in rows):+.2f})")

    lines = [f"## The estimator on {len(rows)} tuning recordings (suite v2's tuning half and "
             f"{len(EXTRA_SEED_SHIFTS)} more draws of each)", "",
             "RMS over the pixels against the true field of the whole rows applied: the check's offset, the fit of "
             "step 3, the field applied after step 5 (the answers with the fit over those of the best offset: "
             f"kept at {MIN_GAIN} or more). Closer / further than the offset by 0.1+ rows: fit {tally(2)}, applied "
             f"{tally(3)}.", "", "| recording | offset | fit | applied | answers fit / best offset |",
             "|---|---:|---:|---:|---:|"]
    lines += [f"| {n} | {c:.2f} | {f:.2f} | {a:.2f} | {'-' if g is None else f'{g:.3f}'} |" for n, c, f, a, g in rows]
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--half", choices=("tune", "eval"), default="tune")
    parser.add_argument("--only", default=None, metavar="NAME,...")
    parser.add_argument("-o", "--output", default="bench/results")
    parser.add_argument("--fits", action="store_true", help="only the fits of the prototype (row-field-fits.md)")
    parser.add_argument("--applied-fit", action="store_true",
                        help="each method with APPLIED_FIT's field, beside row-field.json (row-field-applied.md)")
    parser.add_argument("--package", action="store_true",
                        help="every method with match(row_field=True) beside the default (row-field-package-HALF.md)")
    parser.add_argument("--estimator", action="store_true",
                        help="the package's estimator on the tuning half and extra tuning draws "
                        "(row-field-estimator.md)")
    args = parser.parse_args()
    if args.estimator:
        lines = ["# Rows that differ across the image: the package's estimator on tuning recordings", "",
                 "Generated by `bench/bench_row_field.py --estimator` (`cvstereo.rigcheck.row_field`; the extra "
                 "recordings: `extra_tuning_recordings`).", "", *estimator_table(), "",
                 f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}."]
        (Path(args.output) / "row-field-estimator.md").write_text("\n".join(lines) + "\n")
        print("\n".join(lines))
        return
    if args.package:
        load = os.getloadavg()[0]
        body, rows = package_table(args.half)
        lines = ["# Rows that differ across the image: the package's row field", "",
                 "Generated by `bench/bench_row_field.py --package` (see its docstring; the estimator: "
                 "`cvstereo.rigcheck.row_field`). 'check': `match()` with the default rig check (one row offset); "
                 "'field': `match(row_field=True)`. RMS over the pixels against the true field of the rounded rows "
                 "applied. A recording without a field keeps the check's figures.", "", *body, "",
                 f"2 CPUs, 1-min load average {load:.1f} at the start and {os.getloadavg()[0]:.1f} at the end, "
                 f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}."]
        out = Path(args.output)
        (out / f"row-field-package-{args.half}.md").write_text("\n".join(lines) + "\n")
        (out / f"row-field-package-{args.half}.json").write_text(json.dumps(rows, indent=1, default=float))
        print("\n".join(lines))
        return
    if args.applied_fit:
        lines = ["# Rows that differ across the image: the prototype's field applied", "",
                 "Generated by `bench/bench_row_field.py --applied-fit` (see its docstring and row-field.md).", "",
                 *applied_fit_table(args.half, Path(args.output)), "",
                 f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}."]
        (Path(args.output) / "row-field-applied.md").write_text("\n".join(lines) + "\n")
        print("\n".join(lines))
        return
    if args.fits:
        lines = ["# Rows that differ across the image: fits of the prototype estimator", "",
                 "Generated by `bench/bench_row_field.py --fits` (see its docstring and row-field.md).", "",
                 *fits_table(args.half), "", f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}."]
        Path(args.output).mkdir(parents=True, exist_ok=True)
        (Path(args.output) / "row-field-fits.md").write_text("\n".join(lines) + "\n")
        print("\n".join(lines))
        return
    only = set(args.only.split(",")) if args.only else None
    load = os.getloadavg()[0]
    rows = []
    for name, path in suite_recordings("generalization", half=args.half):
        if only and name not in only:
            continue
        rows.append(one(name, path, args.half))
        r = rows[-1]
        print(f"{name:26s} field {r['field_min']:+.1f}..{r['field_max']:+.1f} applied {r['applied_rows']:+d}  fused "
              f"{_fused_cell(r['as_read'])} -> {_fused_cell(r['oracle'])}  beats both {beats(r['as_read'])} -> "
              f"{beats(r['oracle'])}  ({r['seconds']} s)", flush=True)
    lines = [f"# Rows that differ across the image: the oracle and a prototype ({args.half} half of suite v2)", "",
             "Generated by `bench/bench_row_field.py` (its docstring says what each column is). Bad2 at a peer's "
             "coverage: fused's most certain answers. 'as read': `match()` with the default rig check; 'oracle': "
             "the right rows moved by the true field (rounded), rig check off.", "",
             f"fused better than both peers at parity: as read {sum(beats(r['as_read']) for r in rows)} of "
             f"{len(rows)}, oracle {sum(beats(r['oracle']) for r in rows)} of {len(rows)}.", "", *table(rows)]
    out = Path(args.output)
    out.mkdir(parents=True, exist_ok=True)
    lines += ["", f"2 CPUs, 1-min load average {load:.1f} at the start and {os.getloadavg()[0]:.1f} at the end, "
              f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}."]
    (out / "row-field.md").write_text("\n".join(lines) + "\n")
    (out / "row-field.json").write_text(json.dumps(rows, indent=1, default=float))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
