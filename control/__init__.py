"""The controller side, by concept (docs/architecture.md):

- :mod:`.file`: the trajectory file (format, parser, atomic writer);
- :mod:`.gate`: the validation of a motion and its checks;
- :mod:`.report`: the gate's verdict (findings, the report);
- :mod:`.formats`: ROS 2 messages and bags, the drive table;
- :mod:`.drive`: sampling for the drives (Ruckig), the feed, drive logs, MuJoCo replay,
  the virtual prototype;
- :mod:`.pipeline`: plan, then smooth, validate and write the file.
"""
