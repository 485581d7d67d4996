"""Figures a reviewer would send back (issue 11), checked on the matplotlib artists (no image
comparison): the limit cycles' impact jumps are light and drawn like their legend entry; the
stance-phase torque panel has one curve per joint whatever the number of thrust cases; every
infeasible region of the feasible-region figure is hatched and every legend entry is drawn
exactly as in the plot. The reference values (connected components of the infeasible mask,
the torque envelope) are computed here, independently of the plotting code."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from matplotlib.collections import Collection, LineCollection
from matplotlib.colors import to_rgba
from matplotlib.contour import ContourSet
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from scipy import ndimage

import thrustwalk_cli as tw
from thrustwalk_cli.contact.region import Region
from thrustwalk_cli.plots.feasibility import region_figure

DATA = Path(__file__).parent / "data"
W5_THRUST = [0.0, -5.0, -10.0, -15.0, -20.0, -25.0, -30.0, -35.0, -40.0]  # 9 cases


@pytest.fixture(scope="module")
def walker5(_cache_dir):
    """The user test robot with the gait designed for -40..0 N of its torso thruster."""
    return tw.load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"))


@pytest.fixture(scope="module")
def feas5(walker5):
    return tw.feasibility(walker5, W5_THRUST)


# ------------------------------------------------------------------------------ helpers
def _line_style(line: Line2D) -> tuple:
    """What a reader sees of a line: colour, dash pattern, width, marker, path effects."""
    pe = tuple((type(p).__name__, getattr(p, "_gc", {}).get("linewidth"),
                str(getattr(p, "_gc", {}).get("foreground")))
               for p in line.get_path_effects())
    dashes = line._unscaled_dash_pattern  # (offset, on-off sequence or None)
    return (tuple(np.round(to_rgba(line.get_color()), 6)), str(dashes),
            round(float(line.get_linewidth()), 6), str(line.get_marker()),
            round(float(line.get_markersize()), 6) if line.get_marker() not in ("None", "")
            else None,
            tuple(np.round(to_rgba(line.get_markeredgecolor()), 6))
            if line.get_marker() not in ("None", "") else None,
            pe)


def _legend(ax) -> dict[str, object]:
    leg = ax.get_legend()
    assert leg is not None
    return {t.get_text(): h for t, h in zip(leg.get_texts(), leg.legend_handles)}


def _hatched_paths(ax) -> list:
    """(path in data coordinates, (face, hatch, hatch colour) or None) of every hatched
    artist: patches, collections and filled contour sets (one hatch per level)."""
    out = []
    for art in list(ax.patches) + list(ax.collections):
        if isinstance(art, ContourSet):
            hatches = list(art.hatches or [None])
            if art.filled and any(hatches):
                out += [(path, None) for k, path in enumerate(art.get_paths())
                        if hatches[k % len(hatches)]]
        elif isinstance(art, Patch) and art.get_hatch():
            key = (tuple(np.round(art.get_facecolor(), 6)), art.get_hatch(),
                   tuple(np.round(art.get_edgecolor(), 6)))
            out.append((art.get_patch_transform().transform_path(art.get_path()), key))
        elif isinstance(art, Collection) and art.get_hatch():
            out += [(path, None) for path in art.get_paths()]
    return out


def _covered(ax, points: np.ndarray) -> np.ndarray:
    """Which data points lie under a hatched artist."""
    inside = np.zeros(len(points), bool)
    for path, _ in _hatched_paths(ax):
        inside |= path.contains_points(points)
    return inside


def _cell_points(region, cells: np.ndarray) -> np.ndarray:
    """Grid points (scale, zeta) of the cells, nudged a hair towards the grid centre so the
    points on the grid's border are not on a polygon's edge."""
    s, z = np.asarray(region.scale, float), np.asarray(region.zeta, float)
    p = np.column_stack([s[cells[:, 0]], z[cells[:, 1]]])
    centre = np.array([(s[0] + s[-1]) / 2, (z[0] + z[-1]) / 2])
    return p + 1e-7 * (centre - p)


def _assert_every_infeasible_region_hatched(fig, region) -> int:
    ax = fig.axes[0]
    infeasible = ~np.asarray(region.feasible, bool)
    labels, n = ndimage.label(infeasible)  # 4-connected components, computed here
    for k in range(1, n + 1):
        cells = np.argwhere(labels == k)
        inside = _covered(ax, _cell_points(region, cells))
        assert inside.all(), (f"infeasible region {k} of {n} ({len(cells)} cells): "
                              f"{(~inside).sum()} cells not hatched")
    ok = np.argwhere(~infeasible)
    if len(ok):
        assert not _covered(ax, _cell_points(region, ok)).any(), "a feasible cell is hatched"
    return n


def _synthetic_region(impact_ok: bool = True, eps: float = 20.0, mu: float = 0.7) -> Region:
    """Three disjoint infeasible regions by three conditions: the walker stops (below), the
    contact is lost or the cone is left (above), a friction island in the middle."""
    scale = np.linspace(-50.0, 10.0, 61)
    zeta = np.linspace(50.0, 4000.0, 80)
    S, Z = np.meshgrid(scale, zeta, indexing="ij")
    min_zeta = Z - 413.7 - 4.0 * S  # no grid point exactly on a boundary
    minv = 3007.3 - Z + 10.0 * S
    bump = 0.8 * np.exp(-((S + 20.0) / 6.0) ** 2 - ((Z - 1500.0) / 250.0) ** 2)
    ratio = np.where(minv > 0, 0.3 + 61.3 / np.maximum(minv, 1e-9) + bump, np.inf)
    completes = min_zeta > 0
    feasible = completes & (minv >= eps) & (ratio <= mu) & impact_ok
    fp = 900.0 - 40.0 * scale
    near = np.abs(zeta[None, :] - fp[:, None]).argmin(axis=1)
    fp_ok = feasible[np.arange(scale.size), near]
    return Region(scale, zeta, minv, ratio, completes, feasible, fp, np.ones(scale.size, bool),
                  fp_ok, impact_ok, min_zeta)


# ------------------------------------------------------------------------ limit cycles
def _curves(ax) -> list[tuple[np.ndarray, tuple, float]]:
    """Every curve of ``ax`` whether drawn as a line or as one curve of a line collection:
    (vertices (n, 2) in data units, (colour, dash pattern, width), zorder)."""
    out = []
    for ln in ax.lines:
        xy = np.column_stack([np.asarray(ln.get_xdata(), float),
                              np.asarray(ln.get_ydata(), float)])
        out.append((xy, _line_style(ln)[:3], ln.get_zorder()))
    for c in ax.collections:
        if isinstance(c, LineCollection):
            colours = c.get_colors()
            widths = c.get_linewidths()
            dashes = c._us_linestyles  # unscaled (offset, on-off sequence or None), per curve
            for i, seg in enumerate(c.get_segments()):
                off, seq = dashes[i % len(dashes)]
                style = (tuple(np.round(to_rgba(colours[i % len(colours)]), 6)),
                         str((off, None if seq is None else tuple(seq))),
                         round(float(widths[i % len(widths)]), 6))
                out.append((np.asarray(seg, float), style, c.get_zorder()))
    return out


@pytest.mark.slow
def test_impact_jumps_are_light_behind_the_orbits_and_drawn_like_their_legend(walker3):
    """A 2 N sweep (26 orbits): the jumps are one light, thin style, behind every orbit, and
    the legend's impact entry is that style (on main: one colour per jump, legend grey)."""
    values = list(np.arange(0.0, -51.0, -2.0))
    res = tw.limit_cycle(walker3, values)
    fig = res.figures()["limit_cycles"]
    ax = fig.axes[0]
    zd = walker3.zd
    exist = [c for c in res.cycles if c.exists]
    assert len(exist) == 26
    curves = _curves(ax)
    jumps = [c for c in curves if len(c[0]) == 2
             and np.allclose(c[0][:, 0], [zd.alpha_f, zd.alpha_i])]
    orbits = [c for c in curves if len(c[0]) > 2]
    assert len(jumps) == len(exist) and len(orbits) == len(exist)
    # every jump joins its orbit's pre- and post-impact states
    ends = sorted(tuple(np.round(c[0][:, 1], 9)) for c in jumps)
    want = sorted((round(c.alpha_dot_minus, 9), round(c.alpha_dot_plus, 9)) for c in exist)
    assert ends == want
    styles = {c[1] for c in jumps}
    assert len(styles) == 1, f"{len(styles)} different jump styles"
    jump = jumps[0]
    assert jump[1][2] < min(c[1][2] for c in orbits)
    assert jump[2] < min(c[2] for c in orbits)
    r, g, b, _ = jump[1][0]
    assert 0.2126 * r + 0.7152 * g + 0.0722 * b >= 0.5, "jumps must be light"
    legend = _legend(ax)
    key = [k for k in legend if "impact" in k]
    assert len(key) == 1
    assert _line_style(legend[key[0]])[:3] == jump[1]
    # the orbits' entry is drawn like the black orbits
    black = [c for c in orbits if c[1][0] == to_rgba("k")]
    assert black and any(_line_style(h)[:3] == black[0][1] for h in legend.values())


def _ellipse(cx: float, cy: float, rx: float, ry: float, n: int = 60) -> dict:
    t = np.linspace(0.0, np.pi, n)
    return {"alpha": cx + rx * np.cos(t), "alpha_dot": cy + ry * np.sin(t)}


def test_phase_portrait_draws_each_family_as_one_collection():
    """21 values, one without an orbit: the coloured orbits, the black ones (values that are
    multiples of 10 N) and the impact jumps are three line collections holding exactly the
    given curves in sweep order, coloured by viridis over the sweep's range (computed here),
    black above colour above jumps; legend, colour bar, and saving never lays the figure out
    or searches the legend's place again (on main: one Line2D per curve, legend "best")."""
    import matplotlib
    from matplotlib.legend import Legend

    from thrustwalk_cli.plots.limit_cycle import phase_portrait
    from thrustwalk_cli.plots.style import render

    values = [-2.5 * k for k in range(21)]  # 0 .. -50 N
    orbits = [None if k == 7 else _ellipse(0.0, 1.0 + 0.05 * k, 0.2, 0.5) for k in range(21)]
    jumps = [None if o is None else (0.2, 1.0 + 0.05 * k, -0.2, 0.9 + 0.05 * k)
             for k, o in enumerate(orbits)]
    fig = phase_portrait(values, orbits, jumps, value_label="thrust back [N]", black_every=10.0)
    ax = fig.axes[0]
    assert not [ln for ln in ax.lines if len(ln.get_xdata())]  # no curve as a line
    colls = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(colls) == 3
    black_k = [k for k, v in enumerate(values) if orbits[k] is not None and v % 10.0 == 0.0]
    colour_k = [k for k in range(21) if orbits[k] is not None and k not in black_k]
    assert len(black_k) == 6 and len(colour_k) == 14

    def family(keys):
        want = [np.column_stack([orbits[k]["alpha"], orbits[k]["alpha_dot"]]) for k in keys]
        match = [c for c in colls if len(c.get_segments()) == len(want) and all(
            np.array_equal(s, w) for s, w in zip(c.get_segments(), want))]
        assert len(match) == 1
        return match[0]

    black, coloured = family(black_k), family(colour_k)
    assert np.allclose(black.get_colors(), [to_rgba("k")])
    viridis = matplotlib.colormaps["viridis"]
    assert np.allclose(coloured.get_colors(),
                       [viridis((values[k] + 50.0) / 50.0) for k in colour_k])
    jump = [c for c in colls if c is not black and c is not coloured][0]
    want = [np.array([[0.2, 1.0 + 0.05 * k], [-0.2, 0.9 + 0.05 * k]])
            for k in range(21) if orbits[k] is not None]
    assert len(jump.get_segments()) == 20
    assert all(np.allclose(s, w) for s, w in zip(jump.get_segments(), want))
    assert jump.get_zorder() < coloured.get_zorder() < black.get_zorder()
    assert black.get_linewidths()[0] > coloured.get_linewidths()[0] > jump.get_linewidths()[0]
    legend = _legend(ax)
    assert list(legend) == ["every 10 N", "impact jump"]
    assert _line_style(legend["every 10 N"])[0] == tuple(np.round(to_rgba("k"), 6))
    assert float(legend["every 10 N"].get_linewidth()) == black.get_linewidths()[0]
    assert float(legend["impact jump"].get_linewidth()) == jump.get_linewidths()[0]
    assert np.allclose(legend["impact jump"]._unscaled_dash_pattern[1],
                       jump._us_linestyles[0][1])
    cbar = [a for a in fig.axes if a is not ax]
    assert len(cbar) == 1 and np.allclose(sorted(cbar[0].get_ylim()), [-50.0, 0.0])
    assert "no orbit for -17.5" in " ".join(t.get_text() for t in ax.texts)
    # no data under the legend: the curves leave the lower half of the axes free
    r = fig._get_renderer()
    box = ax.get_legend().get_window_extent(r)
    for c in colls:
        for seg in c.get_segments():
            xy = ax.transData.transform(seg)
            assert not ((xy[:, 0] > box.x0) & (xy[:, 0] < box.x1) & (xy[:, 1] > box.y0)
                        & (xy[:, 1] < box.y1)).any()
    # saving (both formats) neither searches for the legend's place nor lays out again
    before = [a.get_position(original=True).bounds for a in fig.axes]
    search = Legend._find_best_position
    try:
        def refuse(*a, **k):
            raise AssertionError("legend place searched while saving")
        Legend._find_best_position = refuse
        for fmt in ("png", "pdf"):
            assert render(fig, fmt)
    finally:
        Legend._find_best_position = search
    assert [a.get_position(original=True).bounds for a in fig.axes] == before


def _best_of_matplotlib(leg, renderer) -> tuple[float, float]:
    box = leg.get_window_extent(renderer)
    return leg._find_best_position(box.width, box.height, renderer)


def _placed(leg, code, renderer) -> tuple[float, float]:
    from matplotlib.transforms import Bbox

    box = leg.get_window_extent(renderer)
    return leg._get_anchored_bbox(code, Bbox.from_bounds(0, 0, box.width, box.height),
                                  leg.get_bbox_to_anchor(), renderer)


@pytest.mark.parametrize("seed", range(8))
def test_best_legend_loc_is_where_matplotlib_puts_a_best_legend(seed):
    """Random lines, markers, a filled band and a text: best_legend_loc places the legend
    where matplotlib's own "best" search does; and with the same curves as one line
    collection (which matplotlib's search ignores) at the same place as with lines."""
    from matplotlib.figure import Figure

    from thrustwalk_cli.plots.style import best_legend_loc, curve_family

    rng = np.random.default_rng(seed)
    curves = []
    for _ in range(int(rng.integers(2, 7))):
        x = np.linspace(0.0, 1.0, int(rng.integers(2, 60)))
        curves.append((x, rng.random() * x + 0.3 * np.sin(rng.random() * 8 * x)
                       + rng.random()))

    def figure(collection: bool):
        fig = Figure(figsize=(3.5, 2.6))
        ax = fig.subplots()
        if collection:
            curve_family(ax, curves, ["C0"] * len(curves), lw=0.8)
        else:
            for x, y in curves:
                ax.plot(x, y, color="C0", lw=0.8)
        if seed % 2:
            ax.plot(rng.random(15), rng.random(15), "o", ms=2)
        if seed % 3 == 0:
            ax.fill_between([0.0, 1.0], [0.0, 0.3], [0.2, 0.6], color="0.8")
        if seed % 4 == 0:
            ax.text(0.1, 0.9, "a note")
        ax.legend([Line2D([], [], color="C0")], ["curves"], loc="best")
        fig.tight_layout()
        return fig, ax.get_legend(), fig._get_renderer()

    state = rng.bit_generator.state
    fig, leg, r = figure(False)
    code = best_legend_loc(leg, r)
    assert np.allclose(_placed(leg, code, r), _best_of_matplotlib(leg, r))
    rng.bit_generator.state = state
    fig2, leg2, r2 = figure(True)
    assert best_legend_loc(leg2, r2) == code


# ------------------------------------------------------------------------------- grf
def _torque_axis(fig):
    axes = [a for a in fig.axes if "torque" in a.get_ylabel()]
    assert len(axes) == 1
    return axes[0]


@pytest.mark.slow
def test_torque_panel_one_curve_per_joint_whatever_the_cases(walker5, feas5):
    """9 thrust cases x 4 joints on walker5: at most one curve per joint (on main 36), each the
    worst |u| over every case, computed here from the profiles; its peak agrees with the
    polished per-case maxima of the JSON."""
    joints = [c.name for c in walker5.robot.coordinates if c.actuated]
    assert len(joints) == 4 and len(feas5.cases) == 9
    fig = feas5.figures()["grf"]
    ax = _torque_axis(fig)
    curves = [ln for ln in ax.lines if len(ln.get_xdata()) > 1]
    assert len(curves) == len(joints)
    profiles = [c.profile for c in feas5.cases if c.profile is not None]
    assert len(profiles) == 9
    a0 = profiles[0]["alpha"]
    assert all(np.allclose(p["alpha"], a0) for p in profiles)
    env = np.max(np.abs(np.stack([p["torque"] for p in profiles])), axis=0)  # (g, joints)
    polished = np.max([c.max_abs_torque for c in feas5.cases], axis=0)
    for j, name in enumerate(joints):
        match = [ln for ln in curves if np.allclose(ln.get_ydata(), env[:, j], rtol=1e-12,
                                                    atol=1e-9)]
        assert len(match) == 1, name
        assert np.allclose(match[0].get_xdata(), a0)
        peak = env[:, j].max()
        assert peak <= polished[j] * (1 + 1e-9) and peak >= 0.99 * polished[j]
    legend = _legend(ax)
    assert len(legend) == len(joints)
    assert {_line_style(h) for h in legend.values()} == {_line_style(ln) for ln in curves}
    for name in joints:
        assert any(k.startswith(name) for k in legend)
    # fewer cases, same number of curves
    few = tw.feasibility(walker5, [0.0, -20.0, -40.0]).figures()["grf"]
    assert len([ln for ln in _torque_axis(few).lines if len(ln.get_xdata()) > 1]) == 4


# ---------------------------------------------------------------------- feasible region
def test_every_infeasible_region_of_walker5_is_hatched(feas5):
    """walker5 over -48..8 N: stops below, contact lost / cone left above; every infeasible
    cell lies under a hatch (on main the walker-stops region and the cone band are not)."""
    fig = feas5.figures()["feasible_region"]
    n = _assert_every_infeasible_region_hatched(fig, feas5.region)
    assert n >= 2


@pytest.mark.parametrize("impact_ok", [True, False])
def test_every_infeasible_region_is_hatched_whatever_the_condition(impact_ok):
    """Three disjoint infeasible regions by three conditions (stops, contact/cone, a friction
    island), and a region where the impact is inadmissible everywhere (all infeasible)."""
    region = _synthetic_region(impact_ok)
    labels, n = ndimage.label(~region.feasible)
    assert n == (3 if impact_ok else 1)
    fig = region_figure(region, scale_label="thrust [N]", mu=0.7, eps=20.0,
                        cases=[(-20.0, 1700.0)])
    assert _assert_every_infeasible_region_hatched(fig, region) == n


@pytest.mark.parametrize("which", ["walker5", "synthetic"])
def test_region_legend_entries_are_drawn_exactly_as_plotted(which, feas5):
    """Every drawn line and marker (including the fixed-point curve's white outline and its
    infeasible part) has a legend entry of the same colour, dashes, width, marker and path
    effects, and every legend entry is drawn; every hatch has an entry with its face, hatch
    and hatch colour (on main: the fixed points' outline and dotted part have none)."""
    if which == "walker5":
        fig = feas5.figures()["feasible_region"]
        region = feas5.region
    else:
        region = _synthetic_region()
        fig = region_figure(region, scale_label="thrust [N]", mu=0.7, eps=20.0,
                            cases=[(-20.0, 1700.0)])
    ax = fig.axes[0]
    legend = _legend(ax)
    drawn = [ln for ln in ax.lines if np.isfinite(np.asarray(ln.get_ydata(), float)).any()]
    assert not (region.fixed_point_feasible.all())  # both parts of the curve are drawn
    entry_styles = {_line_style(h) for h in legend.values() if isinstance(h, Line2D)}
    for ln in drawn:
        assert _line_style(ln) in entry_styles, f"no legend entry drawn like {ln}"
    contours = [c for c in ax.collections if isinstance(c, ContourSet) and not c.filled]
    contour_styles = {(tuple(np.round(c.get_edgecolor()[0], 6)),
                       round(float(c.get_linewidth()[0]), 6)) for c in contours}
    for h in legend.values():
        if isinstance(h, Line2D):
            st = _line_style(h)
            assert st in {_line_style(ln) for ln in drawn} or (
                (st[0], st[2]) in contour_styles and st[3] == "None"), f"legend entry {h}"
    hatches = {key for _, key in _hatched_paths(ax)}
    assert None not in hatches  # every hatch is a patch with its own style
    entries = {(tuple(np.round(h.get_facecolor(), 6)), h.get_hatch(),
                tuple(np.round(h.get_edgecolor(), 6)))
               for h in legend.values() if isinstance(h, Patch)}
    assert hatches == entries


@pytest.mark.slow
def test_figures_in_a_loop_do_not_grow_memory(walker3):
    """Figures are plain ``matplotlib.figure.Figure`` objects, freed with their last reference:
    a notebook loop of ``result.figures()`` holds no figure in pyplot's registry. The loop is
    25 calls of a stability result's one figure (each call lays out the figure, about 0.1 s;
    traced, 0.25 s: 1,000 would take minutes); the memory traced over the last 10 calls must
    not grow by more than 0.5 MB (one call's figure kept alive is about 0.9 MB), and no figure
    of the loop is alive afterwards. Every other result type: the test below (what keeps
    figures is pyplot's registry, which no module of the package uses) and the limit-cycle
    figures once here (the loop's first result type)."""
    import gc
    import sys
    import tracemalloc
    import weakref

    from matplotlib.figure import Figure

    res = tw.stability(walker3)
    made = []
    for _ in range(15):  # warm the caches (fonts, text metrics)
        made += [weakref.ref(f) for f in res.figures().values()]
    gc.collect()
    tracemalloc.start()
    try:
        for _ in range(10):
            made += [weakref.ref(f) for f in res.figures().values()]
        gc.collect()
        growth = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert growth < 0.5e6, f"memory grew by {growth / 1e6:.2f} MB over 10 figures() calls"
    lc = tw.limit_cycle(walker3, thrust=[0.0, -20.0, -40.0]).figures()
    assert set(lc) == {"limit_cycles", "fixed_point_shift"}
    assert all(type(f) is Figure for f in lc.values())
    made += [weakref.ref(f) for f in lc.values()]
    del lc
    gc.collect()
    assert len(made) == 25 + 2 and all(r() is None for r in made), "a figure is kept alive"
    pyplot = sys.modules.get("matplotlib.pyplot")
    assert pyplot is None or not pyplot.get_fignums()


def test_no_module_of_the_package_draws_through_pyplot():
    """What makes a loop of ``figures()`` grow memory is pyplot's registry, which holds every
    figure made through pyplot (``plt.figure``, ``plt.subplots``) until ``plt.close``: no
    module of the package imports pyplot (every result type's figures are
    ``matplotlib.figure.Figure`` objects), so none of them is registered. The one mention in
    code, ``plots.style.close``, closes a figure made through pyplot elsewhere and imports
    nothing. Checked on the source: every import statement and ``import_module`` call."""
    import re

    imports = re.compile(r"^[ \t]*(import[ \t][^#\n]*\b(pyplot|pylab)\b"
                         r"|from[ \t]+\S*\b(pyplot|pylab)\b"
                         r"|from[ \t]+matplotlib[ \t]+import[ \t][^#\n]*\b(pyplot|pylab)\b)"
                         r"|(import_module|__import__)\(\s*[\"'][^\"'\n]*(pyplot|pylab)", re.M)
    package = Path(tw.__file__).parent
    modules = sorted(package.rglob("*.py"))
    assert len(modules) > 50
    for path in modules:
        hit = imports.search(path.read_text())
        assert hit is None, f"{path.relative_to(package)}: {hit.group(0).strip()}"


def test_simulate_phase_portrait_families_are_collections_of_the_runs_curves():
    """Three runs of five steps (one without a predicted orbit): the transient steps (faint),
    the impacts into each of the last three steps, those steps and the predicted orbits are
    four line collections, each holding exactly those curves in run order with the run's
    colour (viridis over the sweep, computed here) at the family's opacity, stacked transient <
    impacts < settled < predicted (on main: one Line2D per step and per impact)."""
    import matplotlib

    from thrustwalk_cli.plots.simulate import phase_portrait

    def step(k, j):
        a = np.linspace(-0.2, 0.2, 9)
        return {"alpha": a, "alpha_dot": 1.0 + 0.1 * k + 0.01 * j + a ** 2}

    runs = [{"value": v, "failed": False, "steps": [step(k, j) for j in range(5)],
             "predicted": None if k == 1 else {"alpha": np.array([-0.2, 0.0, 0.2]),
                                               "alpha_dot": np.array([2.0, 2.1, 2.2]) + k}}
            for k, v in enumerate([0.0, -5.0, -10.0])]
    fig = phase_portrait({"kind": "constant", "runs": runs}, black_every=None, settled=3)
    ax = fig.axes[0]
    assert not [ln for ln in ax.lines if len(ln.get_xdata())]
    colls = {c.get_zorder(): c for c in ax.collections if isinstance(c, LineCollection)}
    assert sorted(colls) == [1, 2, 3, 4]
    viridis = matplotlib.colormaps["viridis"]
    colour = [viridis((v + 10.0) / 10.0) for v in (0.0, -5.0, -10.0)]

    def check(coll, curves, alpha):
        segs = coll.get_segments()
        assert len(segs) == len(curves)
        for s, (want_xy, _) in zip(segs, curves):
            assert np.allclose(s, want_xy)
        want = [(*colour[k][:3], alpha) for _, k in curves]
        assert np.allclose(coll.get_colors(), want)

    xy = lambda st: np.column_stack([st["alpha"], st["alpha_dot"]])  # noqa: E731
    check(colls[1], [(xy(r["steps"][j]), k) for k, r in enumerate(runs) for j in (0, 1)], 0.18)
    check(colls[3], [(xy(r["steps"][j]), k) for k, r in enumerate(runs) for j in (2, 3, 4)], 1.0)
    check(colls[2], [(np.array([[0.2, r["steps"][j - 1]["alpha_dot"][-1]],
                                [-0.2, r["steps"][j]["alpha_dot"][0]]]), k)
                     for k, r in enumerate(runs) for j in (2, 3, 4)], 0.6)
    check(colls[4], [(np.column_stack([r["predicted"]["alpha"], r["predicted"]["alpha_dot"]]),
                      k) for k, r in enumerate(runs) if r["predicted"] is not None], 1.0)
    assert colls[1].get_linewidths()[0] < colls[3].get_linewidths()[0]
    assert colls[4]._us_linestyles[0][1] is not None  # dashed
    assert list(_legend(ax)) == ["transient", "last 3 steps", "zero-dynamics orbit"]


def _stability_data() -> dict:
    """Five cases over a log-spaced wn sweep, two kinds of multiplier each (a synthetic
    figure input, see ``StabilityResult.figure_data``)."""
    wn = [0.5, 1.58, 5.0, 15.8, 50.0]
    cases = []
    for k, v in enumerate(wn):
        rho = 0.9 * np.exp(-0.3 * k)
        cases.append({"value": v, "verdict": "stable", "spectral_radius": max(rho, 0.4),
                      "re": [rho * np.cos(0.5), rho * np.cos(0.5), 0.4],
                      "im": [rho * np.sin(0.5), -rho * np.sin(0.5), 0.0],
                      "kind": ["thruster", "thruster", "zero dynamics"]})
    return {"cases": cases, "delta_zero_sq": 0.4, "label": r"$\omega_n$ [rad/s]"}


def test_stability_figures_draw_each_kind_of_multiplier_as_one_artist():
    """Each kind of multiplier is one artist holding every case's multipliers of that kind in
    case order: in the complex plane a scatter whose markers are coloured by the swept value
    (viridis on a log scale: the sweep spans two decades; computed here), every marker
    included, the legend's markers grey; against the swept value one marker line per kind
    at the moduli (on main: one Line2D per multiplier, and the first marker of each kind grey,
    recoloured through its legend handle)."""
    import matplotlib
    from matplotlib.collections import PathCollection

    from thrustwalk_cli.plots.stability import multiplier_plane, spectral_radius

    d = _stability_data()
    fig = multiplier_plane(d)
    ax = fig.axes[0]
    viridis = matplotlib.colormaps["viridis"]
    for kind in ("thruster", "zero dynamics"):
        pts = [(re, im, c["value"]) for c in d["cases"]
               for re, im, kd in zip(c["re"], c["im"], c["kind"]) if kd == kind]
        match = [s for s in ax.collections if isinstance(s, PathCollection)
                 and len(s.get_offsets()) == len(pts)
                 and np.allclose(s.get_offsets(), [p[:2] for p in pts])]
        assert len(match) == 1, kind
        want = [viridis(np.log(v / 0.5) / np.log(100.0)) for *_, v in pts]
        assert np.allclose(match[0].get_edgecolors(), want)
        assert len(match[0].get_facecolors()) == 0 or np.allclose(
            match[0].get_facecolors()[:, 3], 0.0)
    legend = _legend(ax)
    assert list(legend) == ["unit circle", r"$\delta_0^2$ (zero dynamics)", "thruster",
                            "zero dynamics"]
    assert to_rgba(legend["thruster"].get_markeredgecolor()) == to_rgba("0.3")
    fig = spectral_radius(d)
    ax = fig.axes[0]
    for kind in ("thruster", "zero dynamics"):
        want = [(c["value"], np.hypot(re, im)) for c in d["cases"]
                for re, im, kd in zip(c["re"], c["im"], c["kind"]) if kd == kind]
        match = [ln for ln in ax.lines if ln.get_label() == kind]
        assert len(match) == 1
        assert np.allclose(np.column_stack([match[0].get_xdata(), match[0].get_ydata()]),
                           want)
        assert match[0].get_linestyle() == "None"
