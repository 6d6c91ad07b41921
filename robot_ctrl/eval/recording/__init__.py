"""Recording a run: recorders and stop conditions for the control loop, fall and run metrics,
the walk's and the drawer task's measurements, the per-tick binary log, the report file.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "fall": ["FallCriterion"],
    "run_metrics": ["RunMetrics"],
    "recorders": ["MetricsRecorder", "ProgressBar", "Fell", "TimeLimit", "HeldFor"],
    "walk_recorder": ["WalkRecorder"],
    "walk_log": ["WalkLog"],
    "drawer_recorder": ["DrawerRecorder"],
    "tick_log": ["TickLog", "open_tick_log", "read_tick_log"],
    "push_capture": ["PushCapture"],
    "report_file": ["write_report"], "hand_error": ["HandError"], "phase_speed": ["PhaseSpeedRecorder"],
})
