"""What the matches' fingerprint of their recording costs beside the fastest matcher (issue 27: under 2 %).

:func:`cvstereo.run.match` takes the fingerprint of the events as read (:mod:`cvstereo.model.fingerprint`) packet by
packet and leaves its time out of ``elapsed_s``. This script measures both on the same packets: the frame
matcher's own time (``elapsed_s``, the ``thesis`` set, the fastest matcher at 640x480) and the fingerprint's
time over the 40 ms packets ``match()`` streams, each repeated until two runs agree within 10 %
(:mod:`cvstereo.benchmark.timing`), and prints events per second of each and the fingerprint's share.

Run on a quiet machine: ``.venv/bin/python bench/bench_fingerprint.py [--seconds S]`` (writes
``bench/results/fingerprint.md``; ``--quick`` for a short smoke run that writes nothing).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from cvstereo.benchmark.timing import measure  # noqa: E402

#: The issue's budget: the fingerprint's time over the fastest matcher's.
BUDGET = 0.02


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=1.0, help="length of the simulated 640x480 clip")
    parser.add_argument("--quick", action="store_true", help="a 0.1 s clip, nothing written")
    args = parser.parse_args(argv)
    import cv2

    from calibration_free import match
    from cvstereo.model.fingerprint import EventFingerprint
    from cvstereo.run import DEFAULT_PACKET_US
    from cvstereo.simulate import simulate
    from cvstereo.simulate.presets import get_preset

    cv2.setNumThreads(1)
    seconds = 0.1 if args.quick else args.seconds
    preset = get_preset("2arms-50cm")
    rec = simulate(preset.scene, rig=preset.rig.for_sensor((640, 480)), seconds=seconds, seed=0)
    packets = list(rec.packets(DEFAULT_PACKET_US))
    events = rec.left.size + rec.right.size

    def fingerprint() -> None:
        fp = EventFingerprint()
        for packet in packets:
            fp.update(packet.left, packet.right)

    match(rec.slice_time(rec.t_start, rec.t_start + 200_000), method="frame", param_set="thesis")  # warm-up
    matcher = measure(lambda: match(rec, method="frame", param_set="thesis").meta["elapsed_s"])
    checksum = measure(fingerprint)
    share = checksum.seconds / matcher.seconds
    lines = [
        "# The fingerprint's cost beside the frame matcher (640x480, thesis set, one process)",
        "",
        f"{events:,} events in {seconds:g} s of `2arms-50cm` at 640x480, packets of {DEFAULT_PACKET_US // 1000} ms; "
        f"load average {matcher.load_before:.2f} before, {checksum.load_after:.2f} after.",
        "",
        "| step | seconds | events/s |",
        "|---|---|---|",
        f"| frame matcher (`elapsed_s`) | {matcher.seconds:.4f} | {events / matcher.seconds:,.0f} |",
        f"| fingerprint | {checksum.seconds:.4f} | {events / checksum.seconds:,.0f} |",
        "",
        f"Fingerprint / matcher: {share:.2%} (budget {BUDGET:.0%}: {'met' if share < BUDGET else 'NOT met'}).",
    ]
    text = "\n".join(lines)
    print(text)
    if not args.quick:
        out = ROOT / "bench" / "results" / "fingerprint.md"
        out.write_text(text + "\n")
        print(f"written: {out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
