"""The certificate's note of quality control: a run made while its rig's control-chart signals stood
acknowledged (rig check ack) says which acknowledgement it ran under (RunCreated's check_ack)."""

from __future__ import annotations

from typing import Any

from rig.report.cert_doc import Block, Heading, Para


def quality_blocks(record: dict[str, Any]) -> list[Block]:
    """A short section when the run was made under an acknowledged signal; none otherwise."""
    ack = record.get("check_ack")
    if not isinstance(ack, dict):
        return []
    signals = [str(s) for s in ack.get("signals") or []]
    listed = "; ".join(signals) if signals else "not listed"
    return [
        Heading("Quality control"),
        Para(
            f"This run was made on rig {ack.get('rig', '?')} after an out-of-control signal of its check "
            f"standard's control charts, acknowledged by {ack.get('who', '?')} at {ack.get('t_utc', '?')} "
            f"(record seq {ack.get('seq', '?')}): {ack.get('why', '?')}. Signal(s): {listed}."
        ),
    ]
