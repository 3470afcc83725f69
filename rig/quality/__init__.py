"""Quality control of the lab's results (ISO/IEC 17025 7.7.1): check standards on control charts.

`charts` is the pure maths; `records` reads the store's check runs into chart series, records
acknowledgements of signals (lab-level `CheckAcknowledged` entries) and says whether a rig may
certify (`RigQuality.refusal`). Comparisons (7.7.2, retained items): `scores` gives ISO 13528's
E_n, z and Algorithm A, `compare` pairs results bat by bat and finds retests (rig compare).
"""

from rig.core.events import CHECK_KIND  # the store's kind of a check run (rig check)

__all__ = ["ACK_KIND", "CHECK_KIND"]

ACK_KIND = "CheckAcknowledged"  # lab-level: signals of a rig's charts acknowledged (rig check ack)
