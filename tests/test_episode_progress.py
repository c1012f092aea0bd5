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


def test_build_bar_shows_the_runs_average_rate_and_keeps_its_width() -> None:
    """The live bar moves by fractions of an episode every second; its rate and ETA stay the
    run's average (tqdm's moving average once showed 463 s/ep for a 19 s build), and a long
    postfix leaves the bar its width."""
    import io
    import re
    import time

    from echo_data.app.build import BAR_WIDTH, build_bar

    out = io.StringIO()
    bar = build_bar(10, 0, "quickstart", disable=False, file=out)
    bar.mininterval = 0
    start = time.monotonic()
    for _ in range(20):
        time.sleep(0.02)
        bar.update(0.01)  # a running episode's share
    bar.update(0.8)  # the episode finishes
    for _ in range(5):
        time.sleep(0.02)
        bar.update(0.002)
    bar.set_postfix_str("2 sampling (scene, acoustics); success 100%, 41.2 steps/s, the whole recipe in ~3 min " * 2)
    elapsed = time.monotonic() - start
    line = out.getvalue().split("\r")[-1]
    bar.close()
    shown = re.search(r"([\d.]+)(s/ep|ep/s)", line)
    assert shown is not None, line
    s_per_ep = float(shown.group(1)) if shown.group(2) == "s/ep" else 1 / float(shown.group(1))
    assert 0.5 * elapsed < s_per_ep < 2.0 * elapsed, line  # ~1 episode done in `elapsed` seconds
    assert re.search(r"%\|[^|]{" + str(BAR_WIDTH) + r"}\|", line), line  # the bar keeps its characters
