"""Final-position error against step size for euler, rk2 and exact, on one manoeuvre.

Two driving histories of the same 10 s manoeuvre on the built-in example robot:

- smooth: wheel velocities that are smooth functions of time, sampled at mid-step and held.
  Euler's error falls with the step (order 1), rk2's and exact's with its square (order 2).
- held: the same manoeuvre as a controller sends it, a new wheel command every 0.1 s and held
  in between, simulated with steps that divide 0.1 s. Exact has no step-size error at all,
  only rounding; euler and rk2 keep theirs.

The reference for both is scipy's ``solve_ivp`` (rtol = atol = 1e-12) on the continuous
unicycle equations, run interval by interval for the held history. Prints the errors and draws
them on log axes.

    pip install -e '.[examples]'
    python examples/step_size_error.py [--output out/figures/step_size_error.png]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp

import diffdrive as dd
from diffdrive.demo import example_robot

DURATION = 10.0  # s
COMMAND_PERIOD = 0.1  # s, for the held history
ROUNDING = 1e-12  # m: below it an error is the floats' rounding, not the method's
ROBOT = example_robot()
STEPS = {  # numbers of steps over the manoeuvre; the held ones divide each command period
    "smooth": [10, 20, 50, 100, 200, 500, 1000, 2000, 5000, 10000],
    "held": [100, 200, 500, 1000, 2000, 5000, 10000],
}


def wheel_velocities(t: np.ndarray) -> np.ndarray:
    """The smooth history, rad/s ``(T, 2)``: drives off, weaves, turns both ways."""
    t = np.asarray(t, dtype=np.float64)
    left = 8.0 + 2.7 * np.cos(0.9 * t) + 0.4 * t
    right = 8.0 - 2.6 * np.cos(1.3 * t) - 0.6 * np.sin(0.4 * t)
    return np.stack([left, right], axis=-1)


def held_commands() -> np.ndarray:
    """The smooth history sampled once per command period, ``(DURATION / period, 2)``."""
    periods = round(DURATION / COMMAND_PERIOD)
    return wheel_velocities((np.arange(periods) + 0.5) * COMMAND_PERIOD)


def reference(pieces: list[tuple[float, float, object]]) -> np.ndarray:
    """The final pose from solve_ivp over ``(t0, t1, wheels(t))`` pieces, one after another."""
    pose = np.zeros(3)
    for t0, t1, wheels in pieces:

        def rates(t, state, wheels=wheels):
            return dd.batch.pose_derivative(state, dd.batch.to_twist(ROBOT, wheels(t)))

        solution = solve_ivp(rates, (t0, t1), pose, method="DOP853", rtol=1e-12, atol=1e-12)
        pose = solution.y[:, -1]
    return pose


def errors(history: str) -> dict[str, list[float]]:
    """Final-position error, m, per method and number of steps, for one history."""
    commands = held_commands()
    if history == "smooth":
        truth = reference([(0.0, DURATION, wheel_velocities)])
    else:
        truth = reference(
            [
                (k * COMMAND_PERIOD, (k + 1) * COMMAND_PERIOD, lambda t, w=w: w)
                for k, w in enumerate(commands)
            ]
        )
    result = {}
    for method in dd.integrate.METHODS:
        result[method] = []
        for steps in STEPS[history]:
            dt = DURATION / steps
            if history == "smooth":
                run = dd.simulate(ROBOT, wheel_velocities, dt=dt, duration=DURATION, method=method)
            else:
                per_command = steps // len(commands)
                run = dd.simulate(
                    ROBOT, np.repeat(commands, per_command, axis=0), dt=dt, method=method
                )
            result[method].append(float(np.hypot(*(run.final_pose[:2] - truth[:2]))))
    return result


def draw(tables: dict[str, dict[str, list[float]]], output: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True, layout="constrained")
    titles = {
        "smooth": "smooth wheel velocities",
        "held": f"commands held for {COMMAND_PERIOD} s",
    }
    for ax, (history, table) in zip(axes, tables.items(), strict=True):
        dts = DURATION / np.array(STEPS[history])
        for method, marker in zip(dd.integrate.METHODS, "os^", strict=True):
            # Exact's error on held commands is rounding, ~1e-16 m: floored so that it shows.
            ax.loglog(dts, np.maximum(table[method], 1e-17), marker=marker, label=method)
        ax.set_title(f"{titles[history]}, {DURATION:.0f} s manoeuvre")
        ax.set_xlabel("step size dt, s")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("final-position error, m")
    axes[0].legend()
    figure.savefig(output, dpi=100)
    plt.close(figure)


def _figure(error: float) -> str:
    """An error as the table prints it: below ``ROUNDING`` m, only that bound (its digits are
    the processor's rounding, which differ between machines)."""
    return f"{'<' + format(ROUNDING, 'g'):>10}" if error < ROUNDING else f"{error:10.1e}"


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=Path("out/figures/step_size_error.png"))
    args = parser.parse_args(argv)
    tables = {history: errors(history) for history in STEPS}
    for history, table in tables.items():
        print(f"{history}: final-position error, m")
        print("  steps " + "".join(f"{s:>10}" for s in STEPS[history]))
        for method, values in table.items():
            print(f"  {method:5} " + "".join(_figure(v) for v in values))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    draw(tables, args.output)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
