"""The viewer's collision layer driven through viser's server API (no browser): the collision
geometry toggle, the colliding links in red, world objects moved with IK following; every shown
answer re-checked here (FK of the shown q, limits, the exact check at the margin)."""

from __future__ import annotations

import socket

import numpy as np
import pytest

pytest.importorskip("viser", reason="the view extra (viser) is not installed")
pytest.importorskip("coal", reason="collision checks need coal (extra 'collision')")

import optik
from optik import spatial
from optik.collision import World, check
from optik.errors import InvalidArgumentError
from optik.view.collisions import CLEAR, HIT, OBJECT

MARGIN = 0.01


def _port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def arm(toy_arm_urdf) -> optik.Mechanism:
    return optik.Mechanism.from_urdf(toy_arm_urdf, "base", "tip")


@pytest.fixture
def viewers():
    made: list = []
    yield made
    for v in made:
        v.close()


def _open(viewers, m, q=None, **options):
    v = optik.view(m, q, port=_port(), **options)
    viewers.append(v)
    return v


def _ball_on_elbow(arm, q) -> World:
    w = World()
    w.add_sphere("ball", 0.05, spatial.translation(*arm.fk(q, "fore")[:3, 3]))
    return w


def test_the_toggle_shows_every_part_where_its_link_is(arm, viewers):
    q = np.array([0.4, -0.7])
    v = _open(viewers, arm, q)
    layer = v.collisions
    assert layer is not None and not layer.colliding  # a clear configuration
    assert len(layer.parts) == len(layer.geo.parts) and not any(h.visible for _, h in layer.parts)
    v.show_collisions(True)
    assert all(h.visible and tuple(h.color) == CLEAR for _, h in layer.parts)
    assert v.panel.collisions.value and "clear by" in v.panel.collision_text.content
    for link, handle in zip(layer.geo.links, layer._links, strict=True):  # placed by FK of the link
        np.testing.assert_allclose(handle.position, arm.fk(q, link)[:3, 3], atol=1e-6)
    v.show_collisions(False)
    assert not any(h.visible for _, h in layer.parts)


def test_colliding_links_and_objects_are_red_even_when_the_geometry_is_hidden(arm, viewers):
    q = np.array([0.3, 1.2])
    w = _ball_on_elbow(arm, q)
    v = _open(viewers, arm, q, world=w, margin=MARGIN, task="position")
    exact = check(arm, q, w, margin=MARGIN)  # the independent query
    hit = {name for p in exact.close_pairs for name in (p.a, p.b)}
    assert exact.in_collision and "ball" in hit
    layer = v.collisions
    assert layer.colliding == hit
    for link, handle in layer.parts:
        red = link in hit
        assert tuple(handle.color) == (HIT if red else CLEAR) and handle.visible == red
    assert tuple(layer.objects["ball"].color) == HIT
    assert "closer than" in v.panel.collision_text.content


def test_moving_an_object_solves_ik_again_around_it(arm, viewers):
    qa, qb = np.array([0.3, 1.2]), np.array([1.5, -1.2])  # two elbow branches of one tip position
    target = optik.Position(arm.fk(qa)[:3, 3])
    w = World()
    w.add_sphere("ball", 0.05, spatial.translation(-1.0, -1.0, 0.0))  # out of the way
    v = _open(viewers, arm, qa + 0.05, world=w, margin=MARGIN, task="position", time_limit=2.0)
    assert v.method == "lm" and set(v.methods) <= {"lm", "nlp"}
    first = v.set_target(target)
    assert first.success
    elbow = arm.fk(v.q, "fore")[:3, 3]
    res = v.move_object("ball", spatial.translation(*elbow))  # onto the shown answer's elbow
    np.testing.assert_allclose(w["ball"].pose[:3, 3], elbow, atol=1e-12)
    np.testing.assert_allclose(v.collisions.gizmos["ball"].position, elbow, atol=1e-6)
    assert res.success, res.message
    shown = v.q
    assert np.linalg.norm(arm.fk(shown)[:3, 3] - target.xyz) <= 1e-6 and arm.within_limits(shown)
    exact = check(arm, shown, w, margin=MARGIN)
    assert not exact.in_collision and exact.min_distance >= MARGIN
    assert not v.collisions.colliding and tuple(v.collisions.objects["ball"].color) == OBJECT
    assert min(np.abs(shown - qb).max(), np.abs(shown - qa).max()) < 1.0  # still a branch of the target


def test_bad_collision_arguments_name_the_argument(arm, viewers):
    with pytest.raises(InvalidArgumentError, match=r"^world"):
        _open(viewers, arm, world="table")
    with pytest.raises(InvalidArgumentError, match=r"^margin"):
        _open(viewers, arm, world=World(), margin=-1.0)
    v = _open(viewers, arm)
    with pytest.raises(InvalidArgumentError, match=r"^name"):
        v.move_object("ball", np.eye(4))  # no world
    w = _ball_on_elbow(arm, np.zeros(2))
    v = _open(viewers, arm, world=w, task="position")
    with pytest.raises(InvalidArgumentError, match=r"^name"):
        v.move_object("shelf", np.eye(4))
    plain = _open(viewers, optik.catalog.planar_2r())  # no collision geometry
    assert plain.collisions is None and plain.panel.collisions is None
    with pytest.raises(InvalidArgumentError, match=r"^on"):
        plain.show_collisions(True)


def test_optik_view_of_a_problem_file_shows_its_world(tmp_path, viewers):
    """``optik view PROBLEM``: the file's ``[world]`` reaches the viewer, drawn and avoided."""
    import textwrap

    from optik.cli import build_parser
    from optik.view.command import _viewer

    path = tmp_path / "panda_box.toml"
    path.write_text(
        textwrap.dedent(
            """
            [problem]
            description = "Two Pandas beside a box"

            [mechanism]
            constructor = "dual_panda"

            [world.box]
            box = [0.1, 0.1, 0.1]
            xyz = [0.6, 0.3, 0.4]
            """
        )
    )
    v = _viewer(build_parser().parse_args(["view", str(path), "--port", str(_port())]))
    viewers.append(v)
    assert v.world is not None and v.world.names == ("box",)
    assert np.allclose(v.world["box"].pose[:3, 3], [0.6, 0.3, 0.4])
    res = v.move_object("box", spatial.translation(0.5, -0.2, 0.5))  # the file's object is draggable
    np.testing.assert_allclose(v.world["box"].pose[:3, 3], [0.5, -0.2, 0.5], atol=1e-12)
    assert v.collisions.gizmos["box"] is not None
    if res.success:  # a shown answer clears the moved box exactly
        assert check(v.m, v.q, v.world, margin=v.margin).min_distance >= v.margin
