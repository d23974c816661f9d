"""The learning page, a marimo app: ``diffdrive learn`` serves it, ``marimo edit`` opens it.

Each section is a cell of controls and a cell that lays out a lesson of
``diffdrive.learn.lessons`` (the numbers, from the library) beside its picture from
``diffdrive.learn.drawings``. Keep the logic there: this file only wires controls to lessons.
"""

import marimo

__generated_with = "0.25.2"
app = marimo.App(width="medium", app_title="diffdrive: differential-drive kinematics")


@app.cell
def _():
    import marimo as mo

    from diffdrive.learn import drawings, lessons

    return drawings, lessons, mo


@app.cell
def _(mo):
    mo.md(r"""
    # Differential-drive kinematics, hands on

    Move the wheels and watch the chassis move. Every number on this page is computed by the
    `diffdrive` library and written into the formulas of the lecture notes (seeds 000 to 004).

    **Conventions** (where they bite, the sections say so again): body $x$ forward, $y$ left;
    the **left wheel is on +y**; $\omega > 0$ turns **left** (counter-clockwise); angles in
    radians, speeds of wheels in rad/s. The notes write **half** the track as $b$, $d$, $D$ or
    $L$; `diffdrive` calls the **full** wheel-to-wheel distance `track_width` $= 2L$.
    """)
    return


@app.cell
def _(mo):
    radius = mo.ui.slider(
        0.01, 0.2, step=0.005, value=0.05, show_value=True, label=r"wheel radius $r$ (m)"
    )
    track = mo.ui.slider(
        0.1, 1.0, step=0.01, value=0.3, show_value=True, label=r"track $2L$, wheel to wheel (m)"
    )
    left = mo.ui.slider(
        -20.0,
        20.0,
        step=0.5,
        value=4.0,
        show_value=True,
        label=r"left wheel $\dot\varphi_L$ (rad/s)",
    )
    right = mo.ui.slider(
        -20.0,
        20.0,
        step=0.5,
        value=10.0,
        show_value=True,
        label=r"right wheel $\dot\varphi_R$ (rad/s)",
    )
    mo.vstack(
        [
            mo.md("## 1. Geometry and forward kinematics: wheel speeds to $(v, \\omega)$"),
            mo.hstack([radius, track], justify="start", gap=2),
            mo.hstack([left, right], justify="start", gap=2),
        ]
    )
    return left, radius, right, track


@app.cell
def _(drawings, left, lessons, mo, radius, right, track):
    forward = lessons.forward_lesson(radius.value, track.value, left.value, right.value)
    mo.hstack(
        [mo.md(forward.markdown()), drawings.forward_picture(forward)], widths=[1, 1], align="start"
    )
    return (forward,)


@app.cell
def _(mo):
    speed = mo.ui.slider(
        -1.5, 1.5, step=0.05, value=1.0, show_value=True, label=r"desired $v$ (m/s)"
    )
    turn = mo.ui.slider(
        -6.0, 6.0, step=0.1, value=2.0, show_value=True, label=r"desired $\omega$ (rad/s)"
    )
    limit = mo.ui.slider(
        1.0, 40.0, step=0.5, value=15.0, show_value=True, label="wheel limit (rad/s)"
    )
    keep = mo.ui.dropdown(["curvature", "omega", "v"], value="curvature", label="keep")
    mo.vstack(
        [
            mo.md(
                "## 2. Inverse kinematics: $(v, \\omega)$ to wheel speeds, within a wheel limit"
                "\n\nThe robot of section 1 ($r$ and $2L$ from there)."
            ),
            mo.hstack([speed, turn], justify="start", gap=2),
            mo.hstack([limit, keep], justify="start", gap=2),
        ]
    )
    return keep, limit, speed, turn


@app.cell
def _(drawings, keep, lessons, limit, mo, radius, speed, track, turn):
    inverse = lessons.inverse_lesson(
        radius.value, track.value, speed.value, turn.value, limit.value, keep.value
    )
    mo.vstack([mo.md(inverse.markdown()), drawings.inverse_picture(inverse)])
    return (inverse,)


@app.cell
def _(mo):
    offset = mo.ui.slider(
        -0.3,
        0.3,
        step=0.01,
        value=0.1,
        show_value=True,
        label="reference point $D$ ahead of the axle (m)",
    )
    mo.vstack(
        [
            mo.md(
                "## 3. The Modern Robotics form: wheel frames, $H$ and its pseudo-inverse\n\n"
                "The wheels of section 1. $V_b = (\\omega, v_x, v_y)$ in the textbook's order."
            ),
            offset,
        ]
    )
    return (offset,)


@app.cell
def _(drawings, left, lessons, mo, offset, radius, right, track):
    modern = lessons.modern_robotics_lesson(
        radius.value, track.value, offset.value, left.value, right.value
    )
    mo.hstack(
        [mo.md(modern.markdown()), drawings.modern_robotics_picture(modern)],
        widths=[1, 1],
        align="start",
    )
    return (modern,)


@app.cell
def _(mo):
    duration = mo.ui.slider(1.0, 20.0, step=0.5, value=6.0, show_value=True, label="duration (s)")
    step = mo.ui.slider(
        steps=[0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0],
        value=0.5,
        show_value=True,
        label="step $h$ (s)",
    )
    mo.vstack(
        [
            mo.md(
                "## 4. Integration: Euler, rk2 and exact against the exact arc\n\n"
                "The wheel speeds of section 1, held for the whole duration: the robot drives "
                "one arc, and each method steps along it."
            ),
            mo.hstack([duration, step], justify="start", gap=2),
        ]
    )
    return duration, step


@app.cell
def _(drawings, duration, left, lessons, mo, radius, right, step, track):
    integration = lessons.integration_lesson(
        radius.value, track.value, left.value, right.value, duration.value, step.value
    )
    mo.vstack([mo.md(integration.markdown()), drawings.integration_picture(integration)])
    return (integration,)


@app.cell
def _(mo):
    # One form, sent when the student presses the button: every value of a check arrives
    # together, so the answer never mixes a new field with an old one.
    check_defaults = {
        "radius": 0.05,
        "track": 0.15,
        "meaning": "half",
        "left": 8.0,
        "right": 10.0,
        "step": 0.1,
        "steps": 3,
        "x": 0.0,
        "y": 0.0,
        "theta": 0.0,
    }

    def number(name, start=None, stop=None):
        return mo.ui.number(start=start, stop=stop, value=check_defaults[name])

    check_form = (
        mo.md(r"""
    $r$ (m) {radius} &nbsp; track value (m) {track} &nbsp; that value is the {meaning}

    $\dot\varphi_L$ (rad/s) {left} &nbsp; $\dot\varphi_R$ (rad/s) {right} &nbsp;
    $T$ (s) {step} &nbsp; $k$ steps {steps}

    $x(0)$ (m) {x} &nbsp; $y(0)$ (m) {y} &nbsp; $\theta(0)$ (rad) {theta}
    """)
        .batch(
            radius=number("radius", start=0.0),
            track=number("track", start=0.0),
            meaning=mo.ui.dropdown(
                {"half track (b, d, D, L)": "half", "full track (2L)": "full"},
                value="half track (b, d, D, L)",
            ),
            left=number("left"),
            right=number("right"),
            step=number("step", start=0.0),
            steps=number("steps", start=1, stop=50),
            x=number("x"),
            y=number("y"),
            theta=number("theta"),
        )
        .form(submit_button_label="Check my answer", bordered=False)
    )
    mo.vstack(
        [
            mo.md(
                "## 5. Check my answer\n\nType the numbers of your problem and press the "
                "button. The wheel speeds are held constant over the $k$ steps. The table is "
                "seed 000's and 002's recurrence, step by step."
            ),
            check_form,
        ]
    )
    return check_defaults, check_form


@app.cell
def _(check_defaults, check_form, drawings, lessons, mo):
    given = check_form.value or check_defaults  # the example until the first check
    try:
        check = lessons.check_answer(
            given["radius"],
            given["track"],
            given["meaning"],
            given["left"],
            given["right"],
            given["step"],
            given["steps"],
            (given["x"], given["y"], given["theta"]),
        )
    except (TypeError, ValueError) as error:
        check = None
        shown = mo.callout(mo.md(f"**Cannot compute this:** {error}"), kind="danger")
    else:
        shown = mo.hstack(
            [mo.md(check.markdown()), drawings.check_picture(check)], widths=[3, 2], align="start"
        )
    shown
    return (check,)


if __name__ == "__main__":
    app.run()
