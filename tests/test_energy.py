"""Energy and cost of transport (SPEC 15): the power models, the power models in the robot
file, and the energies of the zero-dynamics orbit against independent computations (the
work-energy identity from the model's D(q) and V(q), the impact's kinetic-energy loss from the
impact map, the joints' work from the pinned dynamics on a dense grid)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from thrustwalk_cli.description.robot import Motor, ThrusterPower
from thrustwalk_cli.energetics.power import (
    fuel_rate,
    hover_power,
    input_power,
    joint_electrical_power,
    linear_power,
    momentum_power,
    table_power,
)

DATA = Path(__file__).resolve().parent / "data"

MOTORS = ("motor: {torque_constant: 0.05, resistance: 'R0*2', gear_ratio: 100, "
          "gearbox_efficiency: 1}")
POWER = "power: {kind: momentum, diameter: 'lT/2', figure_of_merit: 0.7, motor_efficiency: 0.9}"


def _robot_text(motors: bool = True, power: str = POWER) -> str:
    """walker5 with a motor on every joint (resistance an expression of a new parameter) and a
    power model on its thruster."""
    text = (DATA / "walker5.yaml").read_text().replace("  ls: 0.45\n", "  ls: 0.45\n  R0: 0.3\n")
    if motors:
        for name in ("q_sk", "q_sh", "q_wh", "q_wk"):
            line = next(ln for ln in text.splitlines() if f"{{name: {name}," in ln)
            text = text.replace(line, line[:-1] + ", " + MOTORS + "}")
    return text.replace("limits: [-100, 100]}", f"limits: [-100, 100], {power}}}")


# ------------------------------------------------------------------------ the power models
def test_hover_power_of_a_10N_rotor():
    # by hand: 10^1.5 / sqrt(2 * 1.225 * pi * 0.05^2) = 31.6228 / 0.138716 = 227.97 W
    area = math.pi * 0.1**2 / 4
    assert hover_power(10.0, area, 1.225) == pytest.approx(227.97, abs=0.005)
    assert momentum_power(10.0, area, 1.225, 1.0, 1.0, 0.0) == pytest.approx(227.97, abs=0.005)
    assert momentum_power(-10.0, area) == pytest.approx(227.97, abs=0.005)  # |T|
    # figure of merit and efficiency divide
    assert momentum_power(10.0, area, 1.225, 0.5, 0.8) == pytest.approx(227.97 / 0.4, abs=0.02)


def test_inflow_power_reduces_to_hover_and_is_continuous():
    area = math.pi * 0.1**2 / 4
    T = 10.0
    assert momentum_power(T, area, V=0.0) == hover_power(T, area)
    V = np.linspace(-30.0, 30.0, 600001)  # steps of 1e-4 m/s through V = 0
    P = momentum_power(T, area, V=V)
    assert np.all(np.isfinite(P)) and np.all(P > 0)
    assert np.max(np.abs(np.diff(P))) < 1e-3 * 1e-4 * 1e4  # |dP/dV| < 10 W/(m/s): no jump
    # climbing: the momentum equation T = 2 rho A (V + v_i) v_i holds, P = T (V + v_i)
    for v in (-5.0, 3.0, 20.0):
        p = float(momentum_power(T, area, V=v))
        vi = p / T - v
        assert 2 * 1.225 * area * (v + vi) * vi == pytest.approx(T, rel=1e-12)
    # far above the induced velocity the power tends to the useful power T V
    assert momentum_power(T, area, V=1e4) == pytest.approx(T * 1e4, rel=1e-4)


def test_linear_table_fuel_and_motor_power():
    assert linear_power(-4.0, 12.5) == 50.0
    assert table_power(5.0, [0.0, 10.0], [0.0, 80.0]) == 40.0
    with pytest.raises(ValueError, match="outside the power table's range"):
        table_power(11.0, [0.0, 10.0], [0.0, 80.0])
    assert fuel_rate(-20.0, 1e-4) == pytest.approx(2e-3)
    assert input_power(ThrusterPower("fuel", tsfc=1e-4), 20.0) is None  # no heating value
    assert input_power(ThrusterPower("fuel", tsfc=1e-4, heating_value=4e7), 20.0) == \
        pytest.approx(8e4)
    m = Motor(k_t=0.1, R=2.0, G=10.0, efficiency=0.8)
    # u = 5 N m: i = 5 A, Joule 50 W; motoring 5 * 2 = 10 W / 0.8; generating -10 W * 0.8
    assert joint_electrical_power(5.0, 2.0, m) == pytest.approx(10 / 0.8 + 50)
    assert joint_electrical_power(5.0, -2.0, m) == pytest.approx(-10 * 0.8 + 50)


# ---------------------------------------------------------------------- the robot file
def test_robot_file_reads_motors_and_power_models(tmp_path):
    from thrustwalk_cli.files.robot_file import load_robot_text

    r = load_robot_text(_robot_text(), str(tmp_path / "w.yaml"))
    acts = [c for c in r.coordinates if c.actuated]
    assert all(c.motor == Motor(0.05, 0.6, 100.0, 1.0) for c in acts)  # R = R0 * 2
    p = r.thrusters[0].power
    assert p.kind == "momentum" and p.area == pytest.approx(math.pi * 0.35**2 / 4)
    assert (p.figure_of_merit, p.efficiency, p.rho) == (0.7, 0.9, 1.225)
    plain = load_robot_text((DATA / "walker5.yaml").read_text(), str(tmp_path / "p.yaml"))
    assert plain.thrusters[0].power is None and all(c.motor is None for c in plain.coordinates)
    assert r.structure() == plain.structure()  # energy data never touches the model


@pytest.mark.parametrize("edit, key, message", [
    (lambda t: t.replace("resistance: 'R0*2'", "resistance: -0.5", 1),
     "coordinates.actuated[0].motor.resistance", "must be >= 0"),
    (lambda t: t.replace(POWER, "power: {kind: table, table: {thrust: [0, 10, 5], "
                                "power: [0, 40, 90]}}"),
     "thrusters[0].power.table.thrust[2]", "strictly increasing"),
    (lambda t: t.replace(POWER, "power: {kind: fuel}"), "thrusters[0].power.tsfc",
     "a fuel model needs `tsfc`"),
    (lambda t: t.replace(POWER, "power: {kind: jet, tsfc: 1e-4}"), "thrusters[0].power.kind",
     "must be one of: momentum, linear, table, fuel"),
    (lambda t: t.replace(POWER, "power: {kind: linear, watts_per_newton: 3, tsfc: 1e-4}"),
     "thrusters[0].power.tsfc", "not a key of a linear model"),
])
def test_bad_power_models_are_one_line_errors(cli, tmp_path, monkeypatch, edit, key, message):
    robot = tmp_path / "robots" / "w.yaml"
    robot.parent.mkdir()
    text = edit(_robot_text())
    robot.write_text(text)
    monkeypatch.chdir(tmp_path)
    r = cli("limit-cycle", "robots/w.yaml", str(DATA / "walker5_walk.yaml"), "--out", "o")
    assert r.exit_code == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1, r.stderr
    mark = "name: q_sk" if key.startswith("coordinates") else "name: back"
    line_no = next(i + 1 for i, ln in enumerate(text.splitlines()) if mark in ln)
    assert lines[0].startswith(f"error: robots/w.yaml:{line_no}: {key}: ")
    assert message in lines[0]
    assert not (tmp_path / "o").exists()


# ------------------------------------------------------------------------ the orbit
@pytest.fixture(scope="module")
def orbit5(tmp_path_factory, _cache_dir):
    """walker5 with motors and a momentum rotor, its thrust gait, three constant thrusts
    (0, -20, -40 N on `back`): the orbits and their energies."""
    from thrustwalk_cli.energetics.orbit import orbit_energy
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.thrust.schedule import Schedule
    from thrustwalk_cli.walker import load_walker

    d = tmp_path_factory.mktemp("w5")
    (d / "w.yaml").write_text(_robot_text())
    w = load_walker(str(d / "w.yaml"), str(DATA / "walker5_thrust.yaml"))
    sched = Schedule.on_thruster(w.zd, [0.0, -20.0, -40.0], 0, 1)
    cycles = limit_cycles(w.zd, sched)
    assert all(c.exists for c in cycles)
    return w, sched, cycles, orbit_energy(w.zd, sched, cycles)


def test_orbit_work_energy_identity_and_impact_loss(orbit5):
    w, sched, cycles, energies = orbit5
    model, maps = w.model, w.zd.maps
    for lc, e in zip(cycles, energies):
        # independent: mechanical energy of the model at the two ends of the stance phase
        dq_plus = maps.Phi(np.array(w.zd.alpha_i)) * lc.alpha_dot_plus
        dq_minus = maps.Phi(np.array(w.zd.alpha_f)) * lc.alpha_dot_minus
        E_start = float(model.energy(maps.q_plus, dq_plus))
        E_end = float(model.energy(maps.q_minus, dq_minus))
        work = sum(e.joint_work) + sum(e.thrust_work) + e.generalized_work
        assert work == pytest.approx(E_end - E_start, rel=1e-8, abs=1e-8 * abs(E_end))
        # impact: K^- - K^+ through the model's impact map, >= 0
        imp = model.impact(maps.q_minus, dq_minus)
        K = 0.5 * dq_minus @ model.D(maps.q_minus) @ dq_minus
        Kp = 0.5 * imp.dq_plus @ model.D(imp.q_plus) @ imp.dq_plus
        assert e.impact_loss >= 0
        assert e.impact_loss == pytest.approx(K - Kp, rel=1e-9)
        assert e.step_time == pytest.approx(lc.step_time, rel=1e-9)


def test_orbit_joint_work_against_the_pinned_dynamics(orbit5):
    """Positive and absolute joint work against a dense trapezoid of the torques from the
    pinned dynamics ``u = (D q'' + h - B_F F)_b`` with ``q'' = Phi alpha'' + dPhi alpha'^2``,
    ``alpha''`` differentiated numerically from ``alpha'^2 / 2`` (no stance terms)."""
    w, sched, cycles, energies = orbit5
    model, maps, zd = w.model, w.zd.maps, w.zd
    N = model.n
    a = np.linspace(zd.alpha_i, zd.alpha_f, 20001)
    for r, (lc, e) in enumerate(zip(cycles, energies)):
        F = sched.force[r, 0]
        zeta = lc.zeta_plus + zd.V_Z(a, sched.take([r]))[0]
        k1 = zd.terms(a)["kappa1"]
        ad2 = 2 * k1**2 * zeta  # alpha'^2
        add = np.gradient(ad2 / 2, a, edge_order=2)
        q, phi, dphi = maps.q_Z(a), maps.Phi(a), maps.dPhi(a)
        dq = phi * np.sign(lc.alpha_dot_plus) * np.sqrt(ad2)[:, None]
        ddq = phi * add[:, None] + dphi * ad2[:, None]
        u = (np.einsum("gij,gj->gi", model.D(q), ddq) + model.h(q, dq)
             - model.B_F(q) @ F)[:, :N - 1]
        p = u * dq[:, :N - 1] / (np.sign(lc.alpha_dot_plus) * np.sqrt(ad2))[:, None]
        p = p * np.sign(zd.alpha_f - zd.alpha_i)  # power per |d alpha|
        da = abs(a[1] - a[0])
        trap = lambda f, da=da: (f[1:] + f[:-1]).sum(axis=0) * da / 2  # noqa: E731
        assert np.allclose(e.joint_work, trap(p), rtol=1e-5, atol=1e-5)
        assert np.allclose(e.joint_positive_work, trap(np.maximum(p, 0)), rtol=1e-5,
                           atol=1e-5)
        assert np.allclose(e.joint_absolute_work, trap(np.abs(p)), rtol=1e-5, atol=1e-5)
        # thrust: work F d.p' and the rotor's input power at the axial speed V = sign(F) d.p'
        dp = np.einsum("gn,gnm->gm", dq, model.B_F(q))[:, 0]  # d . p' [m/s]
        adot = np.sqrt(ad2)
        th = w.robot.thrusters[0].power
        P_in = momentum_power(F[0], th.area, th.rho, th.figure_of_merit, th.efficiency,
                              np.sign(F[0]) * dp)
        assert e.thrust_work[0] == pytest.approx(float(trap(F[0] * dp / adot)), rel=1e-6,
                                                 abs=1e-9)
        assert e.thruster_input[0] == pytest.approx(float(trap(P_in / adot)), rel=1e-6,
                                                    abs=1e-9)


def test_orbit_electrical_and_thrust_energy(orbit5):
    w, sched, cycles, energies = orbit5
    p = w.robot.thrusters[0].power
    for r, (lc, e) in enumerate(zip(cycles, energies)):
        F = float(sched.force[r, 0, 0])
        # the Joule loss only adds: clipped electrical energy >= positive mechanical work
        assert all(el >= pw - 1e-12 for el, pw in zip(e.joint_electrical,
                                                       e.joint_positive_work))
        # the rotor moves along its thrust (walking forward, thrust forward): above hover
        hover = float(hover_power(F, p.area, p.rho, p.figure_of_merit, p.efficiency))
        assert hover * lc.step_time <= e.thruster_input[0] <= 1.2 * hover * lc.step_time
        cot = e.cot()
        assert cot["total"] == pytest.approx(cot["total_legs"] + cot["total_thrust"])
        assert cot["mechanical"] == pytest.approx(
            (sum(e.joint_positive_work) + sum(e.thrust_positive_work))
            / (w.robot.weight * lc.step_length))
        assert e.missing == ()
    assert energies[0].thruster_input[0] == 0.0 and energies[0].thrust_work[0] == 0.0


def test_missing_models_are_said_not_zero(tmp_path, _cache_dir):
    from thrustwalk_cli.energetics.orbit import orbit_energy
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.thrust.schedule import Schedule
    from thrustwalk_cli.walker import load_walker

    w = load_walker(str(DATA / "walker5.yaml"), str(DATA / "walker5_thrust.yaml"))
    sched = Schedule.on_thruster(w.zd, [-20.0], 0, 1)
    (e,) = orbit_energy(w.zd, sched, limit_cycles(w.zd, sched))
    rec = e.record()
    assert rec["cot"]["total"] is None and rec["cot"]["mechanical"] > 0
    assert rec["per_step"]["joint_electrical"] == [None] * 4
    assert rec["per_step"]["thruster_input"] == [None]
    assert any("no motor data" in m and "not computed" in m for m in rec["missing"])
    assert any("no power model for thruster back" in m for m in rec["missing"])


# -------------------------------------------------------- the kinks of max(0, .) and |.|
def _exact_abs_and_positive(f, F, roots, half):
    """``int |f|`` and ``int max(0, f)`` over [-1, 1] (times ``half``) from the antiderivative
    ``F`` and the known sign changes ``roots`` of ``f``."""
    pts = np.concatenate([[-1.0], np.sort(roots), [1.0]])
    seg = np.diff(F(pts))
    return np.abs(seg).sum() * half, np.maximum(seg, 0.0).sum() * half


def test_node_tables_in_closed_form_equal_numpy():
    """The tables' ``T_k'`` and ``T_j`` at the Lobatto nodes come from ``cos(k theta)`` and
    ``k sin(k theta) / sin(theta)`` (O(n^2); numpy's chebval of all k at once is O(n^3),
    seconds at the 1,025 nodes of an orbit that comes to rest): numpy's Clenshaw recurrence
    gives the same to rounding, and numpy's chebder the derivative matrices (exact integers
    here)."""
    from numpy.polynomial import chebyshev as Ch

    from thrustwalk_cli.energetics.kinks import (
        _closed_form_tables,
        derivative_matrix,
        node_tables,
    )

    for n in (33, 65, 513):
        x = -np.cos(np.pi * np.arange(n) / (n - 1))
        dT, T2 = _closed_form_tables(n)
        want_dT = Ch.chebval(x, Ch.chebder(np.eye(n))).T
        assert np.abs(T2 - Ch.chebval(x, np.eye(n - 2))).max() <= 1e-11
        assert np.abs(dT - want_dT).max() <= 1e-11 * np.abs(want_dT).max()
        assert np.array_equal(node_tables(n)[6], T2.T)
        D = derivative_matrix(n)  # integers (numpy's chebder divides: rounding)
        assert np.allclose(D[:, :n - 1], Ch.chebder(np.eye(n)).T, rtol=1e-14, atol=0)
        d2 = node_tables(n)[5]
        assert np.array_equal(d2, np.round(d2))
        assert np.allclose(d2, Ch.chebder(np.eye(n), 2).T, rtol=1e-13, atol=0)


def test_kinks_against_known_roots():
    """Rows with known roots, against the exact piecewise integrals: two roots 0.01 apart
    inside one gap of the nodes (about 0.05 wide there), a double root, an oscillating row,
    a constant and a zero row."""
    from numpy.polynomial import Polynomial

    from thrustwalk_cli.energetics.orbit import _abs_and_positive

    n, half = 65, 0.7
    x = -np.cos(np.pi * np.arange(n) / (n - 1))
    cases = []
    for roots, scale in (([-0.5, 0.30, 0.31], 3.0), ([0.2, 0.2, -0.7], -1.0),
                         ([-0.93, 0.111, 0.1125, 0.9], 10.0)):
        p = scale * Polynomial.fromroots(roots)
        simple = [r for r in roots if roots.count(r) % 2 == 1]
        cases.append((p(x), _exact_abs_and_positive(p, p.integ(lbnd=-1), simple, half)))
    # sin(15 x) + 0.2: roots 15 x = -asin(0.2) + 2 pi k and pi + asin(0.2) + 2 pi k
    a0 = math.asin(0.2)
    r = [(c + 2 * math.pi * k) / 15 for k in range(-4, 5) for c in (-a0, math.pi + a0)]
    r = [v for v in r if -1 < v < 1]
    cases.append((np.sin(15 * x) + 0.2, _exact_abs_and_positive(
        None, lambda t: -np.cos(15 * t) / 15 + 0.2 * t, r, half)))
    cases.append((np.full(n, -2.5), (5.0 * half, 0.0)))
    cases.append((np.zeros(n), (0.0, 0.0)))
    ab, po = _abs_and_positive(np.array([c[0] for c in cases]), half)
    for (_, (ea, ep)), a, p in zip(cases, ab, po):
        assert a == pytest.approx(ea, rel=1e-12, abs=1e-15)
        assert p == pytest.approx(ep, rel=1e-12, abs=1e-15)


def _brute_abs_and_positive(values, half, grid=100001):
    """``int |p|`` and ``int max(0, p)`` of each row's Chebyshev interpolant, independently:
    sign changes on a uniform grid of ``grid`` points, bisected to rounding, the
    antiderivative (numpy's ``chebint``) between them."""
    from numpy.polynomial import chebyshev as C

    n = values.shape[1]
    x = -np.cos(np.pi * np.arange(n) / (n - 1))
    t = np.linspace(-1.0, 1.0, grid)
    out = []
    for row in values:
        c = C.chebfit(x, row, n - 1)
        f = C.chebval(t, c)
        i = np.flatnonzero((f[1:] >= 0) != (f[:-1] >= 0))
        a, b, fa = t[i], t[i + 1], f[i]
        for _ in range(60):
            m = 0.5 * (a + b)
            fm = C.chebval(m, c)
            left = (fm >= 0) != (fa >= 0)
            a, b, fa = np.where(left, a, m), np.where(left, m, b), np.where(left, fa, fm)
        seg = np.diff(C.chebval(np.concatenate([[-1.0], 0.5 * (a + b), [1.0]]),
                                C.chebint(c, lbnd=-1)))
        out.append((np.abs(seg).sum() * half, np.maximum(seg, 0.0).sum() * half))
    return np.array(out).T


def test_orbit_kinks_against_brute_force(tmp_path, monkeypatch, _cache_dir):
    """The joint and electrical powers of walker5's walking orbits (their kinks include root
    pairs a few thousandths apart): the piecewise integrals against a brute-force search."""
    import thrustwalk_cli.energetics.orbit as orbit
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.thrust.schedule import Schedule
    from thrustwalk_cli.walker import load_walker

    (tmp_path / "w.yaml").write_text(_robot_text())
    w = load_walker(str(tmp_path / "w.yaml"), str(DATA / "walker5_walk.yaml"))
    sched = Schedule.on_thruster(w.zd, [0.0, -10.0, -20.0], 0, 1)
    rows = []
    real = orbit._abs_and_positive

    def spy(values, half):
        rows.append((values.copy(), half))
        return real(values, half)
    monkeypatch.setattr(orbit, "_abs_and_positive", spy)
    orbit.orbit_energy(w.zd, sched, limit_cycles(w.zd, sched))
    assert sum(v.shape[0] for v, _ in rows) >= 24  # 3 orbits x 4 joints, power and electrical
    for values, half in rows:
        ab, po = real(values, half)
        eab, epo = _brute_abs_and_positive(values, half)
        scale = np.maximum(eab, 1e-300)
        assert np.all(np.abs(ab - eab) <= 1e-12 * scale + 1e-15)
        assert np.all(np.abs(po - epo) <= 1e-12 * scale + 1e-15)


def test_chebyshev_evaluation_against_numpy():
    """The series and its derivative at points (few: powers of e^(i theta); many: Clenshaw)
    against numpy's chebval and chebder, at the ends x = +-1 too (the derivative's limit
    there)."""
    from numpy.polynomial import chebyshev as C

    from thrustwalk_cli.energetics.kinks import SMALL, chebyshev_at

    rng = np.random.default_rng(5)
    n = 65
    for size in (7, SMALL + 40):
        c = rng.standard_normal((n, size)) / (1.0 + np.arange(n)[:, None]) ** 1.5
        x = rng.uniform(-1.0, 1.0, size)
        x[:4] = [-1.0, 1.0, -1.0 + 1e-9, 1.0 - 1e-12]
        val, der = chebyshev_at(np.ascontiguousarray(c), x, derivative=True)
        scale = np.abs(c).sum(axis=0)
        dscale = (np.abs(c) * np.arange(n)[:, None] ** 2).sum(axis=0)
        for r in range(size):
            assert abs(val[r] - C.chebval(x[r], c[:, r])) <= 1e-14 * scale[r]
            assert abs(der[r] - C.chebval(x[r], C.chebder(c[:, r]))) <= 1e-13 * dscale[r]
        assert np.array_equal(chebyshev_at(np.ascontiguousarray(c), x), val)


def test_midpoint_tables_against_numpy():
    """The halvings' middles ``x_g + j h_g / 2^level`` (odd ``j``) and ``T_k``, ``T_k'`` there
    from ``cos(k theta)``, ``k sin(k theta) / sin(theta)`` against numpy's chebval/chebder;
    a series' values and slopes there through the table (up to ``TABLE_LEVELS``) and through
    the general evaluation (beyond) agree."""
    from numpy.polynomial import chebyshev as C

    from thrustwalk_cli.energetics.kinks import (
        TABLE_LEVELS,
        chebyshev_at,
        midpoint_table,
        midpoint_values,
        node_tables,
    )

    n = 65
    xn, h = node_tables(n)[:2]
    eye = np.eye(n)
    for level in range(1, TABLE_LEVELS + 1):
        x, T, dT = midpoint_table(n, level)
        g = np.repeat(np.arange(n - 1), 2 ** (level - 1))
        frac = (x - xn[g]) / h[g]
        assert np.allclose(frac * 2 ** level, np.round(frac * 2 ** level), atol=1e-9)
        assert np.all(np.round(frac * 2 ** level) % 2 == 1)  # odd: a middle, inside the gap
        assert np.abs(T - C.chebval(x, eye)).max() <= 1e-13
        want = C.chebval(x, C.chebder(eye))  # (n, points); |T_k'| <= k^2, the error's scale
        k2 = np.maximum(np.arange(n, dtype=float) ** 2, 1.0)[:, None]
        assert np.all(np.abs(dT - want) <= 1e-13 * k2)
    rng = np.random.default_rng(3)
    cT = rng.standard_normal((n, 9)) / (1.0 + np.arange(n)[:, None]) ** 2
    r = np.array([0, 3, 8, 8])
    for level in (1, TABLE_LEVELS, TABLE_LEVELS + 1):
        g = np.array([0, 17, 40, 63])
        j = np.array([1, 2 ** level - 1, 1, max(1, 2 ** (level - 1) - 1)])  # odd
        p, d, x = midpoint_values(cT, r, n, level, g, j, xn, h)
        pw, dw = chebyshev_at(np.ascontiguousarray(cT[:, r]), x, derivative=True)
        assert np.allclose(x, xn[g] + j * h[g] / 2 ** level, rtol=0, atol=1e-15)
        assert np.allclose(p, pw, rtol=0, atol=1e-13) and np.allclose(d, dw, rtol=0, atol=1e-12)


def test_node_bound_bounds_the_second_derivative():
    """The node bound of the second derivative's size on each gap of the nodes (its size at
    the ends plus half a gap times a bound of the third derivative) is not below the size
    sampled densely on the gap (numpy's chebder), for smooth, oscillating and noisy rows."""
    from numpy.polynomial import chebyshev as C

    from thrustwalk_cli.energetics.kinks import node_bound, node_tables
    from thrustwalk_cli.hzd.quadrature import coefficients

    n = 65
    xn, h, _, _, _, d2, T2, kd, _, _ = node_tables(n)
    rng = np.random.default_rng(7)
    rows = [np.sin(15 * xn) + 0.2, np.exp(xn) * np.cos(3 * xn), 3.0 * (xn + 0.5) * (xn - 0.3),
            rng.standard_normal(n), np.abs(xn) ** 3]
    coef = coefficients(np.array(rows).T).T  # (rows, n)
    gaps = np.arange(n - 1)
    t = np.linspace(0.0, 1.0, 201)
    for c in coef:
        bound = node_bound(np.tile(c @ d2, (n - 1, 1)), gaps, h, T2, kd)
        dd = C.chebder(c, 2)
        for i in gaps:
            assert np.max(np.abs(C.chebval(xn[i] + t * h[i], dd))) <= bound[i]


def test_orbit_energy_from_warm_caches_equals_a_fresh_one(walker3):
    """What orbit_energy keeps on the walker (the alpha-only terms at the nodes, the node
    count where the last call ended) changes no energy: a batch after a larger one equals
    the same batch from empty caches; V_Z from its kept pieces is ZeroDynamics.V_Z; the
    objects equal those of the constructor."""
    import dataclasses

    from thrustwalk_cli.energetics.orbit import OrbitEnergy, _vz, _vz_pieces, orbit_energy
    from thrustwalk_cli.hzd.quadrature import lobatto
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.thrust.schedule import Schedule

    zd = walker3.zd
    m = zd.model.n_thrusters
    big = Schedule.on_thruster(zd, list(np.linspace(0.0, -50.0, 40)), 0, m)
    small = Schedule.on_thruster(zd, [0.0, -25.0], 0, m)
    c_big, c_small = limit_cycles(zd, big), limit_cycles(zd, small)
    for key in ("_energy_nodes", "_energy_node_count"):
        zd.__dict__.pop(key, None)
    fresh = orbit_energy(zd, small, c_small)
    orbit_energy(zd, big, c_big)
    again = orbit_energy(zd, small, c_small)
    for a, b in zip(fresh, again):
        da, db = dataclasses.asdict(a), dataclasses.asdict(b)
        for name in ("joint_work", "joint_positive_work", "joint_absolute_work",
                     "joint_electrical", "thrust_work", "thrust_positive_work",
                     "thruster_input", "step_time"):
            assert np.allclose(da[name], db[name], rtol=1e-12, atol=1e-15), name
        assert b == OrbitEnergy(**db)
    alpha = lobatto(zd.alpha_i, zd.alpha_f, 33)
    kn = np.asarray(big.knots, float)
    assert np.array_equal(_vz(_vz_pieces(zd, alpha, kn), big), zd.V_Z(alpha, big))


def test_limit_cycle_without_energy(walker3):
    """``energy=False`` drops the energy blocks and changes nothing else."""
    import thrustwalk_cli.studies.limit_cycle as lc

    on, off = (lc.limit_cycle(walker3, thrust=[0.0, -10.0], energy=e) for e in (True, False))
    assert off.energy == () and len(on.energy) == 2
    d_on, d_off = on.document(), off.document()
    assert all("energy" not in c for c in d_off["cycles"])
    for c in d_on["cycles"]:
        del c["energy"]
    assert d_on == d_off


def test_electrical_energy_with_a_lossy_gearbox(tmp_path, _cache_dir):
    """Gearbox efficiency 0.8 (``P_m / eta`` motoring, ``P_m eta`` generating: a kink where
    ``P_m`` changes sign): the clipped and the regenerated electrical energy against a dense
    trapezoid of :func:`joint_electrical_power` with the torques of the pinned dynamics."""
    from thrustwalk_cli.energetics.orbit import orbit_energy
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.thrust.schedule import Schedule
    from thrustwalk_cli.walker import load_walker

    (tmp_path / "w.yaml").write_text(_robot_text().replace("gearbox_efficiency: 1",
                                                           "gearbox_efficiency: 0.8"))
    w = load_walker(str(tmp_path / "w.yaml"), str(DATA / "walker5_thrust.yaml"))
    model, maps, zd = w.model, w.zd.maps, w.zd
    N = model.n
    sched = Schedule.on_thruster(zd, [0.0, -30.0], 0, 1)
    cycles = limit_cycles(zd, sched)
    clipped = orbit_energy(zd, sched, cycles)
    regen = orbit_energy(zd, sched, cycles, regenerate=True)
    motors = [c.motor for c in w.robot.coordinates if c.actuated]
    a = np.linspace(zd.alpha_i, zd.alpha_f, 40001)
    da = abs(a[1] - a[0])
    for r, lc in enumerate(cycles):
        F = sched.force[r, 0]
        zeta = lc.zeta_plus + zd.V_Z(a, sched.take([r]))[0]
        ad2 = 2 * zd.terms(a)["kappa1"] ** 2 * zeta
        add = np.gradient(ad2 / 2, a, edge_order=2)
        q, phi, dphi = maps.q_Z(a), maps.Phi(a), maps.dPhi(a)
        adot = np.sqrt(ad2)
        dq = phi * np.sign(lc.alpha_dot_plus) * adot[:, None]
        ddq = phi * add[:, None] + dphi * ad2[:, None]
        u = (np.einsum("gij,gj->gi", model.D(q), ddq) + model.h(q, dq)
             - model.B_F(q) @ F)[:, :N - 1]
        for j, mo in enumerate(motors):
            pe = joint_electrical_power(u[:, j], dq[:, j], mo) / adot  # per |d alpha|
            for f, e in ((np.maximum(pe, 0.0), clipped[r]), (pe, regen[r])):
                ref = (f[1:] + f[:-1]).sum() * da / 2
                assert e.joint_electrical[j] == pytest.approx(ref, rel=2e-6, abs=2e-6)


@pytest.mark.slow
def test_orbit_energies_equal_a_steady_full_order_run(tmp_path, _cache_dir):
    """The zero-dynamics orbit's step energies equal those of a full-order run started on
    that orbit (SPEC 15: to 1e-6), integrated along the run's dense solution: net joint and
    thrust work by Gauss-Legendre, the kinked ones (positive, absolute, clipped electrical)
    by a dense trapezoid, the rotor's input at the axial speed sign(F) d.p'; the impact loss
    against the run's own energies before and after the impact."""
    from thrustwalk_cli.energetics.orbit import orbit_energy
    from thrustwalk_cli.hzd.zero_dynamics import limit_cycles
    from thrustwalk_cli.simulation.closed_loop import SimConfig, ThrustModel
    from thrustwalk_cli.simulation.full_order import simulate
    from thrustwalk_cli.thrust.schedule import Schedule
    from thrustwalk_cli.walker import load_walker

    (tmp_path / "w.yaml").write_text(_robot_text().replace("gearbox_efficiency: 1",
                                                           "gearbox_efficiency: 0.8"))
    w = load_walker(str(tmp_path / "w.yaml"), str(DATA / "walker5_thrust.yaml"))
    zd, model, N = w.zd, w.model, w.model.n
    F = -20.0
    sched = Schedule.on_thruster(zd, [F], 0, 1)
    (e,) = orbit_energy(zd, sched, limit_cycles(zd, sched))
    run = simulate(zd, ThrustModel("ideal", np.array([F])),
                   SimConfig(steps=2, rtol=1e-12, atol=1e-12))
    assert run.success, run.reason
    segs = [s for s in run.segments if s.step == 2]
    ta, tb = segs[0].t0, segs[-1].t1
    assert tb - ta == pytest.approx(e.step_time, rel=1e-9)
    x, wx = np.polynomial.legendre.leggauss(300)
    d = run.sample(2, 0.5 * (tb - ta) * x + 0.5 * (ta + tb))
    wx = 0.5 * (tb - ta) * wx
    dp = np.einsum("gn,gnm->gm", d["dq"], model.B_F(d["q"]))  # d . p' [m/s]
    assert np.allclose((d["u"] * d["dq"][:, :N - 1]).T @ wx, e.joint_work, rtol=1e-6,
                       atol=1e-9)
    assert np.allclose((d["F"] * dp).T @ wx, e.thrust_work, rtol=1e-6)
    t = np.linspace(ta, tb, 40001)
    d = run.sample(2, t)

    def trap(f):
        return ((f[1:] + f[:-1]) * np.diff(t).reshape((-1,) + (1,) * (f.ndim - 1))).sum(0) / 2
    P = d["u"] * d["dq"][:, :N - 1]
    assert np.allclose(trap(np.maximum(P, 0)), e.joint_positive_work, rtol=1e-6)
    assert np.allclose(trap(np.abs(P)), e.joint_absolute_work, rtol=1e-6)
    motors = [c.motor for c in w.robot.coordinates if c.actuated]
    el = [trap(np.maximum(joint_electrical_power(d["u"][:, j], d["dq"][:, j], mo), 0))
          for j, mo in enumerate(motors)]
    assert np.allclose(el, e.joint_electrical, rtol=1e-6)
    p = w.robot.thrusters[0].power
    dp = np.einsum("gn,gnm->gm", d["dq"], model.B_F(d["q"]))[:, 0]
    P_in = momentum_power(F, p.area, p.rho, p.figure_of_merit, p.efficiency, np.sign(F) * dp)
    assert trap(P_in) == pytest.approx(e.thruster_input[0], rel=1e-6)
    rec = run.steps[1]
    assert rec.energy_minus - rec.energy_plus == pytest.approx(e.impact_loss, rel=1e-6)


@pytest.mark.slow
def test_an_orbit_that_comes_to_rest_says_so_instead_of_zero_times(orbit5):
    """Where alpha' = 0 at a quadrature node (zeta^+ lowered until zeta touches 0 inside the
    step: the walker comes to rest), the step time and the time-based energies are not
    computed: None with a reason, never 0 or inf; the works, which do not divide by alpha',
    are still there."""
    import dataclasses

    from thrustwalk_cli.energetics.orbit import orbit_energy

    w, sched, cycles, _ = orbit5
    zd = w.zd
    alpha = np.linspace(zd.alpha_i, zd.alpha_f, 2001)
    vz = zd.V_Z(alpha, sched)[0]
    resting = dataclasses.replace(cycles[0], zeta_plus=float(-vz.min()) - 1.0)
    (e,) = orbit_energy(zd, sched.take(np.array([0])), [resting])
    rec = e.record()
    assert e.step_time is None and rec["average_power"]["legs_mechanical"] is None
    assert all(v is None for v in rec["per_step"]["joint_electrical"])
    assert any("comes to rest" in m for m in rec["missing"])
    assert all(np.isfinite(v) for v in rec["per_step"]["joint_work"])


def test_a_missing_orbit_says_so_once_everywhere(walker3):
    """Thrust that leaves no orbit (pushing the 3-link backwards, zeta* <= 0, SPEC 3): the
    case's verdict, its energy block and the energy study each say "no periodic orbit" once,
    never "no periodic orbit: no periodic orbit"."""
    import json

    from thrustwalk_cli.studies.energy import energy
    from thrustwalk_cli.studies.limit_cycle import limit_cycle

    lc = limit_cycle(walker3, [40.0])
    assert not lc.cycles[0].exists and lc.cycles[0].zeta_star is None
    text = json.dumps(lc.document()) + json.dumps(energy(walker3, [0.0, 40.0]).document())
    assert text.count("no periodic orbit") >= 3
    assert "no periodic orbit: no periodic orbit" not in text
