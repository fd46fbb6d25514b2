"""People walking scripted routes: positions over time, loops, pauses, leaving."""

from __future__ import annotations

import pytest

from missiontree.backends.sim.people import Crowd, Person
from missiontree.backends.sim.schema import PersonSpec


def _person(**kw) -> Person:
    return Person(PersonSpec(id="p", **kw), inst=7)


def test_waits_at_the_first_point_until_start_time():
    """Before start_time the person stands at the first route point."""
    p = _person(route=[[0, 0], [4, 0]], speed=1.0, start_time=5.0, loop=False)
    s = p.state_at(3.0)
    assert (s.x, s.y, s.walking) == (0.0, 0.0, False)


def test_walks_at_constant_speed_along_the_route():
    """Position advances at the set speed along each leg."""
    p = _person(route=[[0, 0], [4, 0], [4, 3]], speed=2.0, loop=False)
    assert (p.state_at(1.0).x, p.state_at(1.0).y) == pytest.approx((2.0, 0.0))
    assert (p.state_at(3.0).x, p.state_at(3.0).y) == pytest.approx((4.0, 2.0))
    end = p.state_at(100.0)
    assert (end.x, end.y, end.walking, end.present) == (4.0, 3.0, False, True)


def test_looping_route_closes_and_repeats():
    """A looping route returns to its start and repeats with its period."""
    p = _person(route=[[0, 0], [3, 0]], speed=1.0, loop=True)
    assert p.state_at(4.5).x == pytest.approx(1.5)   # on the way back
    assert p.state_at(7.0).x == pytest.approx(p.state_at(1.0).x)


def test_pause_at_each_point():
    """With a pause the person stands still at each route point first."""
    p = _person(route=[[0, 0], [2, 0]], speed=1.0, pause=1.5, loop=False)
    assert p.state_at(1.0).x == 0.0 and not p.state_at(1.0).walking
    assert p.state_at(2.5).x == pytest.approx(1.0)


def test_vanish_at_end_leaves_the_world():
    """A non-looping person with vanish_at_end is absent after the route and draws nothing."""
    p = _person(route=[[0, 0], [1, 0]], speed=1.0, loop=False, vanish_at_end=True)
    assert not p.state_at(2.0).present
    assert p.primitives(2.0) == []
    assert Crowd([p]).positions(2.0) == []


def test_legs_torso_and_head_share_the_instance():
    """A person is four prisms (two legs, torso, head) with the person's instance id."""
    p = _person(route=[[1, 1]], speed=0.0)
    rows = p.primitives(0.0)
    assert len(rows) == 4 and {r[5] for r in rows} == {7}
    assert min(r[2] for r in rows) == 0.0 and max(r[3] for r in rows) > 1.6
