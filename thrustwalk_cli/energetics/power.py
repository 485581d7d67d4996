"""Power models of joints and thrusters (SPEC 15): plain formulas on numpy arrays.

Joint motor (torque constant ``k_t`` [N m/A], winding resistance ``R`` [ohm], gear ratio
``G``, gearbox efficiency ``eta_g``), joint torque ``u`` [N m] at joint speed ``q'`` [rad/s]:

    i = u / (G k_t)                                   [A]
    P_el = P_m / eta_g (P_m >= 0)  or  P_m eta_g (P_m < 0),   P_m = u q',   + R i^2   [W]

Negative electrical power (the motor driven backwards, generating) is not recovered by default:
the energy integrates ``max(0, P_el)`` per joint (``regenerate=True`` integrates ``P_el``).

Thruster input power ``P_in`` [W] at thrust ``T`` [N]:

* ``momentum`` (actuator disk, area ``A`` [m^2], air density ``rho`` [kg/m^3], figure of merit
  ``FM``, motor efficiency ``eta``): hover ``|T|^{3/2} / sqrt(2 rho A) / (FM eta)``; with the
  axial air speed ``V`` [m/s] through the disk (positive: the rotor moves along its thrust,
  climb), ``|T| = 2 rho A (V + v_i) v_i`` and ``P_in = |T| (V + v_i) / (FM eta)`` with the
  positive root ``v_i = -V/2 + sqrt(V^2/4 + v_h^2)``, ``v_h^2 = |T| / (2 rho A)``. The same
  root is used for ``V < 0`` (descent): it is smooth, positive and equal to hover at
  ``V = 0``, but momentum theory does not hold in the vortex-ring state ``-2 v_h < V < 0``
  and no power is ever extracted from the air (windmill state): an estimate there.
* ``linear``: ``P_in = w |T|`` (``w`` [W/N]).
* ``table``: measured thrust -> power, linear interpolation (``np.interp``); a thrust
  outside the table's range is refused (``ValueError``: no extrapolation).
* ``fuel``: fuel mass rate ``tsfc |T|`` [kg/s]; input power ``H tsfc |T|`` with a heating
  value ``H`` [J/kg], else unknown.

numpy only: the models are handed their numbers (a :class:`~..description.robot.Motor` or
:class:`~..description.robot.ThrusterPower` is read by attribute).
"""

from __future__ import annotations

import numpy as np


def momentum_power(T, area: float, rho: float = 1.225, figure_of_merit: float = 1.0,
                   efficiency: float = 1.0, V=0.0) -> np.ndarray:
    """Actuator-disk input power [W] of thrust ``T`` [N] at axial air speed ``V`` [m/s]
    (module docstring; ``V = 0``: hover, ``|T|^{3/2} / sqrt(2 rho A) / (FM eta)``)."""
    T = np.abs(np.asarray(T, float))
    V = np.asarray(V, float)
    vh2 = T / (2.0 * rho * area)
    vi = -0.5 * V + np.sqrt(0.25 * V * V + vh2)
    return T * (V + vi) / (figure_of_merit * efficiency)


def hover_power(T, area: float, rho: float = 1.225, figure_of_merit: float = 1.0,
                efficiency: float = 1.0) -> np.ndarray:
    """``|T|^{3/2} / sqrt(2 rho A) / (FM eta)`` [W]: momentum theory in hover."""
    T = np.abs(np.asarray(T, float))
    return T ** 1.5 / np.sqrt(2.0 * rho * area) / (figure_of_merit * efficiency)


def linear_power(T, watts_per_newton: float) -> np.ndarray:
    """``w |T|`` [W]."""
    return watts_per_newton * np.abs(np.asarray(T, float))


def table_power(T, thrust, power) -> np.ndarray:
    """Measured ``thrust`` [N] (strictly increasing) -> ``power`` [W], interpolated linearly at
    ``T``; ``ValueError`` for a thrust outside the table's range."""
    T = np.asarray(T, float)
    x = np.asarray(thrust, float)
    out = (T < x[0]) | (T > x[-1])
    if np.any(out):
        bad = T[out].flat[0]
        raise ValueError(f"thrust {bad:g} N is outside the power table's range "
                         f"[{x[0]:g}, {x[-1]:g}] N")
    return np.interp(T, x, np.asarray(power, float))


def fuel_rate(T, tsfc: float) -> np.ndarray:
    """Fuel mass rate ``tsfc |T|`` [kg/s]."""
    return tsfc * np.abs(np.asarray(T, float))


def input_power(model, T, V=0.0) -> np.ndarray | None:
    """Thruster input power [W] of a power ``model`` (a ``ThrusterPower``) at thrust ``T`` [N]
    and axial air speed ``V`` [m/s] (momentum only); None for a fuel model without a heating
    value (only the fuel mass is known). ``ValueError`` outside a table's range."""
    k = model.kind
    if k == "momentum":
        return momentum_power(T, model.area, model.rho, model.figure_of_merit,
                              model.efficiency, V)
    if k == "linear":
        return linear_power(T, model.watts_per_newton)
    if k == "table":
        return table_power(T, model.thrust, model.power)
    if k == "fuel":
        if model.heating_value is None:
            return None
        return model.heating_value * fuel_rate(T, model.tsfc)
    raise ValueError(f"unknown power model kind {k!r}")


def joint_electrical_power(u, qdot, motor) -> np.ndarray:
    """Electrical power [W] of a joint motor (``k_t``, ``R``, ``G``, ``efficiency``) giving
    torque ``u`` [N m] at joint speed ``qdot`` [rad/s]: ``P_m / eta_g`` when ``P_m = u q' >=
    0``, ``P_m eta_g`` otherwise, plus the Joule loss ``R (u / (G k_t))^2`` (module
    docstring). Negative values: the motor generates (clip them for no recovery)."""
    u = np.asarray(u, float)
    pm = u * np.asarray(qdot, float)
    eta = motor.efficiency
    mech = np.where(pm >= 0.0, pm / eta, pm * eta)
    return mech + joule_power(u, motor)


def joule_power(u, motor) -> np.ndarray:
    """Winding loss ``R i^2`` [W], ``i = u / (G k_t)`` [A]."""
    i = np.asarray(u, float) / (motor.G * motor.k_t)
    return motor.R * i * i


def missing_models(robot) -> list[str]:
    """The lines that say which power models the robot file does not give (SPEC 15: a part
    whose model is missing is None with a reason, never 0)."""
    acts = [c for c in robot.coordinates if c.actuated]
    missing = []
    names = [c.name for c in acts if c.motor is None]
    if names:
        missing.append(f"no motor data for {', '.join(names)}: joint electrical energy not "
                       "computed (a `motor:` per actuated coordinate in the robot file)")
    for t in robot.thrusters:
        p = t.power
        if p is None:
            missing.append(f"no power model for thruster {t.name}: its input energy not "
                           "computed (a `power:` in the robot file)")
        elif p.kind == "fuel" and p.heating_value is None:
            missing.append(f"thruster {t.name}: a fuel model without `heating_value`: fuel "
                           "mass only, input energy not computed")
    return missing
