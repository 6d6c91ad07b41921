"""Campaigns: many trials, each a ``robot-ctrl`` command in its own process group, run locally
or on a Ray cluster, resumable after a kill; the drawer and robustness campaigns and their summaries.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "campaign_runner": ["run_campaign"],
    "campaign_backends": ["open_backend"],
    "trial_process": ["Trial", "TrialOutcome"],
    "drawer_campaign": ["run_drawer_campaign"],
    "robustness_campaign": ["run_robustness"],
    "feasible_demonstrations": ["record_feasible_set"],
})
