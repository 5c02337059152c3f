"""actaim2.profiling: exclusive section times while a profile records, nothing otherwise."""

import time

from actaim2.profiling import Profile, recording, section, timed


@timed("outer")
def _outer() -> None:
    time.sleep(0.02)
    with section("inner"):
        time.sleep(0.03)


def test_nested_sections_count_in_the_innermost_only():
    profile = Profile()
    with recording(profile):
        started = time.perf_counter()
        _outer()
        _outer()
        wall = time.perf_counter() - started
    assert profile.calls == {"outer": 2, "inner": 2}
    assert 0.05 <= profile.seconds["inner"] < wall
    assert 0.03 <= profile.seconds["outer"] < wall - profile.seconds["inner"] + 1e-9


def test_nothing_is_recorded_without_a_profile():
    profile = Profile()
    _outer()  # no recording profile: sections do nothing
    with section("alone"):
        pass
    assert profile.seconds == {} and profile.calls == {}
    with recording(profile):
        with section("alone"):
            pass
    _outer()  # after the block: not recorded either
    assert profile.calls == {"alone": 1}
