"""Evaluation: what a run is judged by, measured in the simulation.

- ``recording``: recorders the control loop calls each tick (falls, torques, GRF, the walk's and the
  drawer's measurements, the per-tick log) and the report.json they give.
- ``reports``: the HTML report of a run and of campaigns, and their figures.
- ``campaigns``: many trials run locally or on Ray, resumably, and their summaries.
"""
