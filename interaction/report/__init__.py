"""The safety report per plan for the integrator's risk assessment (docs/safety.md,
"The safety report"): its numbers, the gate's own (``safety_report.py``), and its page
(``safety_page.py``)."""
