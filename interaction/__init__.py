"""Physical interaction, sensorless: what a person does to the robot, from the drives
alone, and what the robot does about it (docs/architecture.md, "Contact safety, module
by module").  One concept per sub-package:

- :mod:`sixplus3.interaction.observer`: the external torque and wrench from the drives
  (the one momentum observer; the batch estimate, the 1 kHz stream and its compiled
  state; force resolution; docs/interaction.md);
- :mod:`sixplus3.interaction.envelope`: what every controller may read and must command
  (the reading check, the drive's rate model, the whole command within the envelope);
- :mod:`sixplus3.interaction.contact`: the contact guard that runs a validated file and
  stops, holds or retracts on a contact (docs/safety.md);
- :mod:`sixplus3.interaction.lead`: lead-through and teach (docs/leadthrough.md);
- :mod:`sixplus3.interaction.report`: the safety report per plan for the integrator;
- :mod:`sixplus3.interaction.people`: the runs that put the guard or lead-through in the
  loop with a simulated person or hand (the people themselves, test harnesses, sit
  beside the plant they drive: :mod:`sixplus3.control.drive.person`,
  :mod:`sixplus3.control.drive.hand`).
"""
