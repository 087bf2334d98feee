"""Tests of optik.plot: figures for every catalog mechanism, geometry, atomic saving."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import optik
from optik import plot, problem_files
from optik.errors import InvalidArgumentError

MECHANISMS = problem_files.default_constructors()
CATALOG = [getattr(optik.catalog, name) for name in MECHANISMS if hasattr(optik.catalog, name)]


@pytest.mark.parametrize("build", CATALOG, ids=lambda f: f.__name__)
def test_draw_and_branches_for_every_catalog_mechanism(build):
    m = build()
    rng = np.random.default_rng(3)
    ax = plot.draw(m, m.mid_q())
    assert ax.name == ("rectilinear" if m.planar else "3d")
    assert ax.lines, "nothing was drawn"
    qs = [m.random_q(seed=rng) for _ in range(3)]
    fig = plot.draw_branches(m, qs, title="three")
    assert len(fig.axes) == 3
    assert all(a.name == ax.name for a in fig.axes)


@pytest.mark.parametrize("name", ["five_bar", "stewart_gough"])
def test_saved_figures_are_pngs(name, tmp_path):
    m = getattr(optik.catalog, name)()
    out = plot.save_figure(plot.draw_branches(m, [m.mid_q()]), tmp_path / "fig.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_draw_branches_without_branches_says_so():
    fig = plot.draw_branches(optik.catalog.planar_2r(), [])
    assert len(fig.axes) == 1
    assert "no configuration" in fig.axes[0].texts[0].get_text()


def test_spatial_mechanism_needs_3d_axes():
    from matplotlib.figure import Figure

    m = optik.catalog.seed_6r_arm()
    ax2d = Figure().add_subplot()
    with pytest.raises(InvalidArgumentError, match="ax"):
        plot.draw(m, m.mid_q(), ax=ax2d)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3))
def test_planar_3r_joint_locations_are_the_partial_sums(q):
    m = optik.catalog.planar_3r(lengths=(1.0, 0.8, 0.5))
    g = plot.geometry(m, q)
    angles = np.cumsum(q)
    tips = np.cumsum(
        np.column_stack(
            [np.array([1.0, 0.8, 0.5]) * np.cos(angles), np.array([1.0, 0.8, 0.5]) * np.sin(angles)]
        ),
        axis=0,
    )
    np.testing.assert_allclose(g.parent_side[1:, :2], tips[:2], atol=1e-12)
    np.testing.assert_allclose(g.ee[:2, 3], tips[2], atol=1e-12)
    np.testing.assert_allclose(g.ee, m.fk(q), atol=1e-12)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-np.pi, np.pi), min_size=4, max_size=4))
def test_five_bar_cut_joint_gap_is_the_closure_residual(q):
    m = optik.catalog.five_bar()
    g = plot.geometry(m, q)
    cut = m.topology.cuts[0]
    gap = np.linalg.norm(g.child_side[cut] - g.parent_side[cut])
    assert gap == pytest.approx(np.linalg.norm(m.closure(q)), abs=1e-12)


def test_prismatic_joint_spans_its_stroke():
    m = optik.catalog.pp_arm()
    g = plot.geometry(m, [0.3, -0.7])
    np.testing.assert_allclose(g.child_side[0] - g.parent_side[0], [0.3, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(g.child_side[1] - g.parent_side[1], [0.0, -0.7, 0.0], atol=1e-12)


@pytest.mark.parametrize("build", CATALOG, ids=lambda f: f.__name__)
def test_workspace(build):
    m = build()
    n = 40 if m.planar or not m.is_closed else 8
    fig = plot.workspace(m, n=n, seed=1)  # every catalog mechanism has an FK (no skip)
    assert len(fig.axes) == 1
    pts, modes, drawn = plot.workspace_points(m, n=n, seed=1)
    assert drawn == n and len(pts) == len(modes)
    if not m.is_closed:
        assert len(pts) == n
        np.testing.assert_allclose(pts, m.fk(m.random_q(n, seed=1))[:, :3, 3])


def test_workspace_rejects_bad_n():
    with pytest.raises(InvalidArgumentError, match=r"^n:"):
        plot.workspace(optik.catalog.planar_2r(), n=0)


def test_save_is_atomic_and_cleans_up(tmp_path):
    target = tmp_path / "sub" / "x.txt"
    plot.write_atomic(target, lambda tmp: Path(tmp).write_text("hello"))
    assert target.read_text() == "hello"
    assert target.stat().st_mode & 0o644 == 0o644  # readable by others, like a normal file

    def boom(tmp):
        Path(tmp).write_text("partial")
        raise RuntimeError("disk full")

    with pytest.raises(RuntimeError):
        plot.write_atomic(target, boom)
    assert target.read_text() == "hello"
    assert sorted(p.name for p in target.parent.iterdir()) == ["x.txt"]
    with pytest.raises(InvalidArgumentError, match="path"):
        plot.save_figure(plot.draw_branches(optik.catalog.planar_2r(), []), tmp_path / "noext")
    with pytest.raises(InvalidArgumentError, match=r"^path: unsupported image format 'zzz'"):
        plot.save_figure(plot.draw_branches(optik.catalog.planar_2r(), []), tmp_path / "fig.zzz")
    assert not list(tmp_path.glob("fig*"))
