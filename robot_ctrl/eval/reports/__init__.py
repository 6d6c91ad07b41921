"""Reports: a run's self-contained report.html and its figures, and the pages of campaigns.
"""

from robot_ctrl.lazy_exports import lazy_exports

__all__, __getattr__, __dir__ = lazy_exports(__name__, {
    "html_report": ["render_report"],
    "campaign_report": ["render_campaign"],
    "robustness_report": ["render_robustness"],
    "group_walk_report": ["TouchdownRecorder"],
})
