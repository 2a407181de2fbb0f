"""The controllers met by simulated people: :func:`~.person.run_contact` builds the
contact guard and runs it with a body region in the robot's way, :func:`~.hand.run_lead`
builds lead-through and runs it with a hand guiding the platform.  The people
themselves (ISO/TS 15066's two-body model, the hand's spring-damper) are test harnesses
beside the plant they drive: ``control/drive/person.py`` and ``control/drive/hand.py``
(docs/safety.md, docs/leadthrough.md)."""
