"""The simulated people who meet the virtual prototype: a body region in the robot's
way (``person.py``, ISO/TS 15066's two-body model; docs/safety.md) and a hand that
guides the platform (``hand.py``; docs/leadthrough.md).  They drive the MuJoCo plant
through the one drive loop (control/drive/loop.py) with a controller in it: test
harnesses and benchmarks, not parts a controller uses."""
