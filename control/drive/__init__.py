"""The drive side: sampling a plan for the drives (Ruckig), the feed, drive logs, the
MuJoCo replay and the virtual prototype."""
