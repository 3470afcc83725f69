"""Quality control of the lab's results (ISO/IEC 17025 7.7.1): check standards on control charts.

`charts` is the pure maths; `records` reads the store's check runs into chart series, records
acknowledgements of signals (lab-level `CheckAcknowledged` entries) and new phase I's
(`CheckRestarted`), says whether a rig may certify (`RigQuality.refusal`); `crosscheck` charts the
model cross-check's standardised residuals of the certified runs. Comparisons (7.7.2, retained
items): `scores` gives ISO 13528's E_n, z and Algorithm A, `compare` pairs results bat by bat and
finds retests (rig compare).
"""

from rig.core.events import CHECK_ACKNOWLEDGED as ACK_KIND  # lab-level: signals acknowledged (rig check ack)
from rig.core.events import CHECK_KIND  # the store's kind of a check run (rig check)
from rig.core.events import CHECK_RESTARTED as RESTART_KIND  # lab-level: a new phase I (rig check restart)

__all__ = ["ACK_KIND", "CHECK_KIND", "RESTART_KIND"]
