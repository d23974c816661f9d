"""io.stamps: the sample times behind stamps that are a clock tick early at times."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from diffdrive.io.stamps import sample_times

TICK = 1e-3


def published(count, period, phase, early, drops, seed):
    """The true sample times (the first tick past ``phase + k period``) of ``count`` messages
    less the ``drops`` dropped ones, and their stamps, a share ``early`` of them a tick early."""
    rng = np.random.default_rng(seed)
    ideal = 100.0 + phase + np.arange(count) * period
    truth = np.ceil(np.round(ideal / TICK, 9)) * TICK
    kept = np.sort(rng.choice(count, count - drops, replace=False))
    kept = np.union1d([0, 1], kept)  # the first two stay: the period is seen from the start
    truth = truth[kept]
    stamps = truth - TICK * (rng.random(len(truth)) < early)
    return truth, stamps


def test_the_turtlebot3_joint_states_are_restored_to_the_simulators_ticks():
    from data import data_folder
    from diffdrive.io import ros

    bag = data_folder("ros-bags") / "turtlebot3_fuse.bag"
    run = ros.read_joint_states(bag, "wheel_left_joint", "wheel_right_joint")
    found = sample_times(run.times)
    assert found.period == pytest.approx(1 / 30, rel=1e-5)
    assert (found.moved, len(run.times)) == (441, 2741)
    moved = np.round((found.times - run.times) / TICK)
    assert set(moved.tolist()) == {0.0, 1.0}

    def noise(times):  # the robust spread of the velocities' second differences, rad/s
        velocity = np.diff(run.wheels, axis=0) / np.diff(times)[:, None]
        return np.median(np.abs(np.diff(velocity, 2, axis=0))) / 0.6745 / np.sqrt(6)

    assert noise(run.times) > 0.07
    assert noise(found.times) < 0.005


@pytest.mark.slow
@settings(max_examples=60, deadline=None)
@given(
    st.floats(5.0, 60.0),  # the period in ticks
    st.floats(-2.0, 2.0),  # its phase, ticks
    st.floats(0.0, 0.3),  # the share of stamps a tick early
    st.integers(0, 5),  # messages dropped
    st.integers(0, 2**32 - 1),
)
# A phase exactly on a tick and no stamp early: every stamp fits its own tick only in a band
# of periods narrower than the search's grid, and outside the least-squares period's errors.
@example(5.004421133413485, 0.0, 0.0, 0, 0)
# A period near a whole number of ticks, the phase on a tick: the ticks' rounding is a slow
# sawtooth that pulled the least-squares period 6 of its errors from the truth, past the search.
@example(5.002888051991725, 0.0, 0.25, 3, 0)
@example(5.002888051991725, 0.0, 0.25, 0, 0)
# Six samples a tick off: the times found leave 113 stamps early where the truth leaves 117, so
# the stamps bear them out better than the truth, and cannot tell the two apart.
@example(5.923904726687521, 1.0390625, 0.25, 4, 317)
def test_any_period_phase_and_early_share_is_restored(period, phase, early, drops, seed):
    """Every sample time within a tick of the truth, all but a few (2 %) exactly, and never
    fewer stamps on their ticks than the truth has (where the stamps cannot tell, the most)."""
    truth, stamps = published(400, period * TICK, phase * TICK, early, drops, seed)
    found = sample_times(stamps, TICK, share=0.5)
    miss = np.round((found.times - truth) / TICK)
    np.testing.assert_allclose(found.times, truth + miss * TICK, rtol=0, atol=1e-9)
    assert np.all(np.abs(miss) <= 1)
    assert np.count_nonzero(miss) <= 0.02 * len(truth)
    early_in_truth = int(np.sum(np.round((truth - stamps) / TICK)))
    assert found.moved <= early_in_truth
    assert found.moved == int(np.sum(np.round((found.times - stamps) / TICK)))


def test_a_first_stamp_that_is_itself_early_is_restored():
    truth, stamps = published(300, 0.1 / 3, 0.0, 0.1, 0, 3)
    stamps[0] = truth[0] - TICK
    np.testing.assert_allclose(sample_times(stamps).times, truth, rtol=0, atol=1e-9)


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda t: t + np.random.default_rng(0).uniform(-3e-3, 3e-3, len(t)), "wander"),
        (lambda t: np.where(np.arange(len(t)) == 150, t - 2 * TICK, t), "1 lie further"),
        (lambda t: t - TICK * (np.arange(len(t)) % 2), "at least 80% on them"),
        (lambda t: np.arange(len(t)) * 4e-3, "spans under 5 ticks"),
        (lambda t: np.sort(np.concatenate([t[:-1], [t[5] + 1e-4]])), "within half a period"),
        (lambda t: np.where(np.arange(len(t)) == 7, np.nan, t), "finite and increase"),
        (lambda t: t[:5], "N >= 10"),
    ],
)
def test_stamps_that_are_not_a_period_on_ticks_are_refused(change, message):
    _, stamps = published(300, 0.1 / 3, 0.0, 0.1, 0, 1)
    with pytest.raises(ValueError, match=message):
        sample_times(change(stamps))


@pytest.mark.parametrize(("options", "message"), [({"tick": 0.0}, "tick"), ({"share": 0}, "share")])
def test_a_tick_or_share_out_of_range_is_refused(options, message):
    _, stamps = published(100, 0.1 / 3, 0.0, 0.1, 0, 1)
    with pytest.raises(ValueError, match=message):
        sample_times(stamps, **options)
