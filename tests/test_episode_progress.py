"""The build's bar moves inside a running episode: workers' step counts reach the bar via shared slots."""

from multiprocessing import get_context

from echo_data.app import episode_progress as ep


def test_slots_carry_steps_and_clear_before_the_result() -> None:
    slots, counter = ep.make_slots(2, get_context("spawn"))
    ep.install(slots, counter)
    try:
        ep.prepare()  # sampling the scene: no steps yet, counted as sampling, not as progress
        assert ep.preparing(slots) == 1 and ep.running_fraction(slots, None) == 0.0
        ep.begin(200)
        assert ep.preparing(slots) == 0
        assert ep.running_fraction(slots, None) == 0.0
        ep._last = 0.0  # the throttle lets the next write through
        ep.step(50)
        assert ep.running_fraction(slots, None) == 0.25  # 50 of the 200-step budget
        assert ep.running_fraction(slots, 100.0) == 0.5  # 50 of the 100 steps a finished episode took
        ep.step(60)  # within INTERVAL of the last write: not written (no per-step traffic)
        assert slots[0] == 50
        ep._last = 0.0
        ep.step(500)
        assert ep.running_fraction(slots, 100.0) == 0.95  # a running episode never counts as finished
        ep.end()
        assert ep.running_fraction(slots, 100.0) == 0.0
    finally:
        ep.uninstall()


def test_step_without_a_build_is_a_no_op() -> None:
    ep.uninstall()
    ep.begin(10)
    ep.step(5)
    ep.end()
