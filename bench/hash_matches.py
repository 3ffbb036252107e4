"""A sha256 of the matches of every method x variant on a short simulated clip: proof that a refactor kept them.

Simulates the first 2 s of the ``2arms-50cm`` preset (seed 0), runs every installed matcher variant on it
(the thesis' five, the OpenCV baselines, dv-processing where installed) under the ``thesis`` parameter set
(the thesis' constants, which these hashes pin; ``--param-set adaptive`` for the default set) and prints one
line per variant: ``method/variant sha256``. Run it before and after a change and compare the outputs
(``--check FILE`` exits 1 when any hash differs).

    python bench/hash_matches.py > before.txt
    python bench/hash_matches.py --check before.txt
    python bench/hash_matches.py --check before.txt --threads 1    # and on one thread, and on 3

The committed ``bench/results/matches_hashes.txt`` pins the ``thesis`` set. The ``adaptive`` set changes on
purpose when its defaults are tuned, so its hashes are only compared before and after a refactor that must
keep them (a speed-up).
"""

from __future__ import annotations

import argparse
import hashlib
import sys

from calibration_free import available_methods, match, matcher_class
from cvstereo.simulate import simulate_preset


def matches_hashes(seconds: float = 2.0, seed: int = 0, param_set: str = "thesis",
                   threads: int | None = None) -> dict[str, str]:
    """``method/variant`` -> sha256 of the matches array's bytes, for every installed method, under
    ``param_set``, on ``threads`` (None: the library's default, the cores; the hashes must not depend on it)."""
    rec = simulate_preset("2arms-50cm", seconds=seconds, seed=seed)
    out = {}
    for method in available_methods():
        for variant in matcher_class(method).variants:
            # The matchers alone: the default rig check of match() is geometry, not what these hashes pin.
            result = match(rec, method=method, variant=variant, param_set=param_set, rig_check=False,
                           threads=threads)
            out[f"{method}/{variant}"] = hashlib.sha256(result.matches.tobytes()).hexdigest()
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--param-set", choices=("thesis", "adaptive"), default="thesis",
                        help="parameter set of every run (default: thesis, which the committed file pins)")
    parser.add_argument("--check", metavar="FILE", help="compare with the lines of an earlier run")
    parser.add_argument("--threads", type=int, default=None, metavar="N",
                        help="threads of every matcher (default: the cores); the hashes are the same on any number")
    args = parser.parse_args(argv)
    hashes = matches_hashes(args.seconds, param_set=args.param_set, threads=args.threads)
    lines = [f"{label} {digest}" for label, digest in hashes.items()]
    print("\n".join(lines))
    if args.check:
        with open(args.check) as fh:
            before = dict(line.split() for line in fh if line.strip())
        differ = [label for label, digest in hashes.items() if before.get(label) != digest]
        missing = sorted(set(before) - set(hashes))
        for label in differ:
            print(f"DIFFERS: {label}", file=sys.stderr)
        for label in missing:
            print(f"MISSING: {label}", file=sys.stderr)
        if differ or missing:
            return 1
        print(f"all {len(hashes)} hashes identical", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
