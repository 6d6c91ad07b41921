"""``robot-ctrl`` command line: one subcommand per user-facing task, one module per command family
(``robot_runs``: balance, walk, drawer, robustness; ``crowd``; ``campaign``; ``synth``; ``hw``;
``tools``: report, log, robots), the options they share (``options``, ``simulation``) and the
entry point (``command_line``)."""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "command_line": ["build_parser", "main"],
})
