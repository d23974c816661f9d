"""The noise model's terms found again over seeds of synthetic runs of known noise
(``tests/test_noise.py``'s scenario), and what identifying costs.

Per seed: 200 runs of a robot whose wheels carry random-walk noise of 1e-4 m (left) and
3e-4 m (right), in 40 groups of 5 that share one draw of the geometry (radii 0.5 % and
0.8 correlated, track 1 %). Against motion capture held at its stated accuracy
(``noise.MOTION_CAPTURE``, runs of 10 s), and against a reference of 5 mm and 0.01 rad fitted
with the rest (runs of 10 s and 20 s, 8 and 10 windows), it prints the share of seeds in
which each term lies within 10 % of the truth and within two of its standard errors, the
median relative error of each, and the median seconds one identification takes.

    python benchmarks/bench_noise_model.py [--seeds 20]
"""

from __future__ import annotations

import argparse
import platform
import sys
import time
from pathlib import Path

import numpy as np

from diffdrive.calibration import noise

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from test_noise import HELD, MOTION_CAPTURE, ROBOT, TRUE, TRUE_REF, found_terms, runs

# (the reference, held at its accuracy, seconds a run, windows a run)
SETTINGS = (
    ("motion capture, held", True, 10, 8),
    ("5 mm, 0.01 rad, fitted", False, 10, 8),
    ("5 mm, 0.01 rad, fitted", False, 20, 10),
)


def one_seed(seed: int, held: bool, seconds: float, windows: int) -> tuple[dict, dict, float]:
    times = np.arange(round(seconds / 0.02) + 1) * 0.02
    reference = MOTION_CAPTURE if held else TRUE_REF
    groups, _ = runs(200, seed=seed, per_group=5, times=times, reference=reference)
    start = time.perf_counter()
    if held:
        model = noise.identify(ROBOT, groups, windows=windows, terms=noise.TERMS[:4], fixed=HELD)
    else:
        model = noise.identify(ROBOT, groups, windows=windows)
    spent = time.perf_counter() - start
    return found_terms(model), model.standard_errors(), spent


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    args = parser.parse_args(argv)
    print(
        f"machine: {platform.machine()}, {platform.processor() or 'cpu'}, Python "
        f"{platform.python_version()}, NumPy {np.__version__}; {args.seeds} seeds\n"
    )
    print("| reference | runs | term | within 10 % | within 2 SE | median error |")
    print("|---|---|---|---|---|---|")
    for reference, held, seconds, windows in SETTINGS:
        results = [one_seed(seed, held, seconds, windows) for seed in range(args.seeds)]
        setting = f"| {reference} | {seconds} s, {windows} windows"
        for name, true in TRUE.items():
            if held and name in HELD:
                continue
            errors = np.array([found[name] / true - 1 for found, _, _ in results])
            honest = np.mean([abs(f[name] - true) <= 2 * se[name] for f, se, _ in results])
            print(
                f"{setting} | {name} | {np.mean(np.abs(errors) <= 0.1):.0%} | {honest:.0%} | "
                f"{np.median(np.abs(errors)):.1%} |"
            )
        spent = np.median([s for _, _, s in results])
        print(f"{setting} | one identification | | | {spent:.1f} s |")


if __name__ == "__main__":
    main()
