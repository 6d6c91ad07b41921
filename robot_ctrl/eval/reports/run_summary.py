"""What a run's report says first: its title (the task and its parameters), its verdict and its key
figures, each against its goal or limit, read from ``report.json`` alone. One function per kind of
run (drawer task, walk, balance demo, group walk, tick log), chosen by the fields the report has.

The goals are the task's own criteria where it has them (the drawer task's, ``drawer_recorder``),
the thesis's bars (steps within 10 mm, Fig. 3.41; torques and forces within the robot's limits,
Fig. 3.47), and otherwise stated here: a walk ends within 5 cm of its goal, the balance demo's hand
within 1 cm of its target, the measured ZMP inside the support polygon on at least 99 % of the
contact samples.
"""

from __future__ import annotations

from robot_ctrl.eval.recording.drawer_recorder import (
    COMFORT_TOLERANCE,
    OBJECT_TOLERANCE,
    OPENED_SHARE,
    STEP_TOLERANCE,
    drawer_criteria,
    failed_criteria,
)
from robot_ctrl.eval.reports.page import KeyFigure, Summary, Verdict

GOAL_TOLERANCE = 0.05  # [m] a walk's final position error that still counts as at its goal
HAND_TOLERANCE = 0.01  # [m] the balance demo's hand to its target at the end of the hold
ZMP_IN_SUPPORT_GOAL = 0.99  # share of contact samples with the measured ZMP in the support polygon

#: The unit each report.json key suffix stands for, longest first.
SUFFIX_UNITS = (("_ns_per_kg", "N·s/kg"), ("_per_s", "1/s"), ("_mps", "m/s"), ("_nm", "N·m"), ("_deg", "°"),
                ("_rad", "rad"), ("_ms", "ms"), ("_hz", "Hz"), ("_m", "m"), ("_s", "s"), ("_n", "N"))


def summarize(report: dict) -> Summary:
    """The title, verdict and key figures of any run's report."""
    if "slot" in report:
        return _drawer(report)
    if "goal" in report:
        return _walk(report)
    if "hand_target_floor_m" in report:
        return _balance(report)
    if "robots" in report and "certified_phase_rate_per_s" in report:
        return _group_walk(report)
    if "ticks" in report:
        return _tick_log(report)
    return Summary(f"Run — {_robot(report)}", _fell_or(report, Verdict(None, "Ran to its end")), ())


def unit_of(key: str) -> tuple[str, str]:
    """(the key without its unit suffix, the unit): ``("drawer_opening", "m")`` for ``drawer_opening_m``."""
    for suffix, unit in SUFFIX_UNITS:
        if key.endswith(suffix):
            return key[: -len(suffix)], unit
    return key, ""


def quantity(value: float, unit: str) -> str:
    """A number with its unit as a person reads it: lengths under 10 cm in millimetres."""
    if unit == "m" and abs(value) < 0.1:
        return f"{value * 1000:.1f} mm"
    if unit == "m":
        return f"{value:.3f} m"
    if unit in ("", "ratio"):
        return f"{value:.3g}"
    return f"{value:.4g} {unit}".replace(" °", "°")


def _metres(value: float) -> str:
    """A distance as the user typed it, with at least one decimal: 2.0, 1.45."""
    text = f"{value:g}"
    return text if "." in text or "e" in text else f"{value:.1f}"


def _robot(report: dict) -> str:
    name = str(report.get("robot", "robot")).replace("_", " ")
    return name[:1].upper() + name[1:]


def _fell_or(report: dict, otherwise: Verdict) -> Verdict:
    if report.get("fell"):
        t = report.get("fall_time_s")
        when = "" if t is None else f" at {t:.2f} s"
        return Verdict(False, f"Fell{when}: {report.get('fall_reason') or 'reason not recorded'}")
    return otherwise


def _limits(report: dict) -> list[KeyFigure]:
    """What every physics run is judged by: torques and forces within the limits, no safety
    intervention, the ZMP in the support polygon."""
    out = []
    if "peak_torque_ratio" in report:
        ratio = report["peak_torque_ratio"]
        joint = str(report.get("peak_torque_joint", "")).replace("_joint", "")
        out.append(KeyFigure("Peak servo torque / limit", f"{ratio:.2f} ({joint})", "≤ 1", ratio <= 1.0,
                             "peak_torque_ratio"))
    grf, limit = report.get("peak_grf_n"), report.get("grf_limit_n")
    if isinstance(grf, dict) and grf:
        peak = max(grf.values())
        out.append(KeyFigure("Peak vertical ground force", f"{peak:.0f} N",
                             "" if limit is None else f"≤ {limit:.0f} N",
                             None if limit is None else peak <= limit, "peak_grf_n"))
    if isinstance(report.get("safety"), dict):
        count = sum(report["safety"].get("interventions", {}).values())
        out.append(KeyFigure("Safety-layer interventions", f"{count}", "0", count == 0, "safety.interventions"))
    if "zmp_in_support_ratio" in report and report["zmp_in_support_ratio"] is not None:
        share = report["zmp_in_support_ratio"]
        out.append(KeyFigure("Measured ZMP in the support polygon", f"{share:.1%}", f"≥ {ZMP_IN_SUPPORT_GOAL:.0%}",
                             share >= ZMP_IN_SUPPORT_GOAL, "zmp_in_support_ratio"))
    return out


def _drawer(report: dict) -> Summary:
    slot = str(report["slot"]).replace("_", "-")
    extras = [f"{report['speed']} speed" if report.get("speed", "nominal") != "nominal" else "",
              f"{report['method']} method" if report.get("method", "ours") != "ours" else "",
              "jumping goal" if report.get("goal_jumps") or report.get("cabinet_moves") else ""]
    cabinet = report.get("cabinet")
    where = (f"{_metres(report['distance_m'])} m" if cabinet is None else
             f"cabinet at ({cabinet['x_m']:g}, {cabinet['y_m']:g}) m facing {cabinet['front_yaw_deg']:g}° in a room")
    title = ", ".join([f"Drawer task — {_robot(report)}", where, f"{slot} slot",
                       *[e for e in extras if e]])
    step = report.get("step_length_error_max_m")
    pelvis, comfort = report.get("final_pelvis_to_drawer_m"), report.get("comfort_distance_m")
    opening, required = report.get("drawer_opening_m"), report.get("drawer_opening_required_m")
    hand = report.get("hand_to_object_m")
    met = drawer_criteria(report)
    opened = None if opening is None or required is None else met["drawer opened"]
    figures = [
        KeyFigure("Drawer opening", "–" if opening is None else f"{opening * 100:.1f} cm",
                  "" if required is None
                  else f"≥ {OPENED_SHARE:.0%} of {required * 100:.0f} cm (the hand's clearance)",
                  opened, "drawer_opening_m"),
        KeyFigure("Right hand to the object", "–" if hand is None else quantity(hand, "m"),
                  f"≤ {OBJECT_TOLERANCE * 1000:.0f} mm", None if hand is None else met["object reached"],
                  "hand_to_object_m"),
        KeyFigure("Largest step-length error", "–" if step is None else quantity(step, "m"),
                  f"≤ {STEP_TOLERANCE * 1000:.0f} mm (thesis Fig. 3.41)",
                  None if step is None else met["steps within 10 mm"], "step_length_error_max_m"),
        KeyFigure("Pelvis to the drawer at the end", "–" if pelvis is None else f"{pelvis:.3f} m",
                  "" if comfort is None else f"{comfort:.3f} ± {COMFORT_TOLERANCE * 1000:.0f} mm (comfort)",
                  None if pelvis is None or comfort is None else met["pelvis at the comfort distance"],
                  "final_pelvis_to_drawer_m"),
    ]
    failed = failed_criteria(report)
    if report.get("success"):
        verdict = Verdict(True, "Success: the drawer opened, the object reached, every step within 10 mm, "
                                "the pelvis at the comfort distance")
    else:
        verdict = Verdict(False, "Failed: " + (", ".join(f"not {name}" for name in failed) or "a criterion"))
    if report.get("drawer_pull_force_peak_n") is not None:
        figures.append(KeyFigure("Peak pull on the drawer", f"{report['drawer_pull_force_peak_n']:.1f} N",
                                 "from the contacts", key="drawer_pull_force_peak_n"))
    if report.get("unintended_contacts") is not None:
        figures.append(KeyFigure("Other contacts with the furniture",
                                 f"{report['unintended_contacts']}, peak {report['unintended_force_peak_n']:.0f} N",
                                 "the arm, body or wrong hand on the cabinet, drawer or objects",
                                 key="unintended_contacts"))
    return Summary(title, _fell_or(report, verdict), tuple(figures + _limits(report)))


def _walk(report: dict) -> Summary:
    goal = report["goal"]
    if goal.get("lateral_m"):
        path = f"{abs(goal['lateral_m']):g} m sideways to the {'left' if goal['lateral_m'] > 0 else 'right'}"
    elif goal.get("turn_deg"):
        path = f"{_metres(goal['distance_m'])} m arc turning {goal['turn_deg']:g}°"
    else:
        path = f"{_metres(goal['distance_m'])} m straight"
    pushes = report.get("disturbances", {}).get("pushes") or []
    title = f"Walk — {_robot(report)}, {path} at {goal['speed_mps']:g} m/s" + (f", {len(pushes)} push"
                                                                               f"{'es' if len(pushes) > 1 else ''}"
                                                                               if pushes else "")
    error, yaw = report.get("final_position_error_m"), report.get("final_yaw_error_deg")
    at_goal = error is not None and error <= GOAL_TOLERANCE
    verdict = Verdict(at_goal, f"Walked to the goal: ended {quantity(error, 'm')} and {yaw:.2f}° from it"
                      if at_goal else f"Ended away from the goal ({'–' if error is None else quantity(error, 'm')})")
    figures = [KeyFigure("Final position error", "–" if error is None else quantity(error, "m"),
                         f"≤ {GOAL_TOLERANCE * 100:.0f} cm", None if error is None else at_goal,
                         "final_position_error_m"),
               KeyFigure("Final heading error", "–" if yaw is None else f"{yaw:.2f}°", key="final_yaw_error_deg")]
    steps = report.get("step_length_error_m") or []
    if steps:
        worst = max(abs(s) for s in steps)
        figures.append(KeyFigure("Largest step-length error", quantity(worst, "m"),
                                 f"≤ {STEP_TOLERANCE * 1000:.0f} mm",
                                 worst <= STEP_TOLERANCE, "step_length_error_m"))
    if report.get("com_error_rms_m") is not None:
        figures.append(KeyFigure("CoM tracking error, RMS", quantity(report["com_error_rms_m"], "m"),
                                 key="com_error_rms_m"))
    return Summary(title, _fell_or(report, verdict), tuple(figures + _limits(report)))


def _balance(report: dict) -> Summary:
    hand = report.get("hand_error_m")
    ok = hand is not None and hand <= HAND_TOLERANCE
    verdict = Verdict(ok, "Stood through the weight shift, foot lift and reach; the hand "
                          f"{'–' if hand is None else quantity(hand, 'm')} from its target")
    figures = [KeyFigure("Right hand to its target after the hold", "–" if hand is None else quantity(hand, "m"),
                         f"≤ {HAND_TOLERANCE * 1000:.0f} mm", None if hand is None else ok, "hand_error_m")]
    return Summary(f"Balance demo — {_robot(report)}", _fell_or(report, verdict), tuple(figures + _limits(report)))


def _group_walk(report: dict) -> Summary:
    gains = report.get("gains", {})
    graph = {"all": "all-to-all"}.get(report.get("graph"), report.get("graph"))
    title = (f"Group walk — {report['n']} × {_robot(report)}, {graph} coupling, "
             f"k = {gains.get('k', '–')}")
    fell = [i for i, r in enumerate(report["robots"]) if r.get("fell")]
    synced = report.get("synchronized_after_s")
    if fell:
        verdict = Verdict(False, f"Robot{'s' if len(fell) > 1 else ''} {', '.join(map(str, fell))} fell")
    elif synced is None:
        verdict = Verdict(False, "The gaits did not synchronize")
    else:
        verdict = Verdict(True, f"Synchronized {synced:.2f} s after the coupling came on; nobody fell")
    tolerance = report.get("sync_tolerance_rad", 0.1)
    spread = report.get("final_phase_spread_rad")
    rate, certified = report.get("empirical_phase_rate_per_s"), report.get("certified_phase_rate_per_s")
    figures = [KeyFigure("Final phase spread", "–" if spread is None else f"{spread:.3f} rad",
                         f"< {tolerance:g} rad", None if spread is None else spread < tolerance,
                         "final_phase_spread_rad"),
               KeyFigure("Phase convergence rate, measured", "–" if rate is None else f"{rate:.2f} 1/s",
                         "" if certified is None else f"≥ {certified:.2f} 1/s (certified)",
                         None if rate is None or certified is None else rate >= certified,
                         "empirical_phase_rate_per_s")]
    if report.get("final_position_spread_m") is not None:
        figures.append(KeyFigure("Positions abreast, spread", quantity(report["final_position_spread_m"], "m"),
                                 key="final_position_spread_m"))
    peaks = [r["peak_torque_ratio"] for r in report["robots"] if "peak_torque_ratio" in r]
    if peaks:
        figures.append(KeyFigure("Peak servo torque / limit, any robot", f"{max(peaks):.2f}", "≤ 1",
                                 max(peaks) <= 1.0,
                                 "robots[].peak_torque_ratio"))
    return Summary(title, verdict, tuple(figures))


def _tick_log(report: dict) -> Summary:
    title = f"Tick log — {_robot(report)}, {report['ticks']} ticks"
    figures = []
    if report.get("tracking_error_max_rad") is not None:
        figures.append(KeyFigure("Largest tracking error", f"{report['tracking_error_max_rad']:.3f} rad "
                                 f"({str(report.get('tracking_error_max_joint', '')).replace('_joint', '')})",
                                 key="tracking_error_max_rad"))
    return Summary(title, _fell_or(report, Verdict(None, "Logged to its end")), tuple(figures + _limits(report)))
