"""The lab's identity for its test reports (ISO/IEC 17025 7.8.2.1 b): name, address, accreditation id
and an optional logo, read from a TOML file (table [lab]) and recorded whole in a run at its start,
so that a report is built from the record, never from a file read when it is rendered.

The logo is embedded (base64) in the record: a PNG or JPEG of at most LOGO_BYTES, checked by its
magic bytes; SVG is refused (it may carry script). Every refusal is one ConfigError naming the file.
"""

from __future__ import annotations

import base64
import hashlib
import os
from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, BaseModel, ConfigDict, Field

from rig.core.errors import ConfigError
from rig.core.files import read_bounded
from rig.core.tomlfile import read_toml, table, validate

LAB_ENV = "RIG_LAB"  # the environment variable that names the lab identity file
LOGO_BYTES = 256_000  # a letterhead logo is a few tens of kB
_MAGIC = {b"\x89PNG\r\n\x1a\n": "image/png", b"\xff\xd8\xff": "image/jpeg"}


def printable(text: str) -> str:
    """`text` stripped, if every line of it is printable (no control characters, no markup risk
    beyond what the report escapes); ValueError otherwise."""
    if not all(line.isprintable() for line in text.split("\n")):
        raise ValueError("only printable characters (and line breaks) are allowed")
    if not text.strip():
        raise ValueError("must not be blank")
    return text.strip()


Line = Annotated[str, Field(min_length=1, max_length=200), AfterValidator(printable)]
Lines = Annotated[str, Field(min_length=1, max_length=600), AfterValidator(printable)]


class LabIdentity(BaseModel):
    """Table [lab] of a lab identity file."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    name: Line
    address: Lines
    accreditation_id: Line | None = None  # None: the lab states no accreditation
    logo: Annotated[str, Field(min_length=1, max_length=500)] | None = None  # an image file, relative to this


def load_lab(path: str | Path) -> dict[str, Any]:
    """The lab identity of file `path` as a run records it: name, address, accreditation_id, and
    the logo embedded ({media_type, sha256, data_b64, file}) or None."""
    source = str(path)
    lab = validate(
        LabIdentity, table(read_toml(path, what="a lab identity file"), "lab", source), source, "lab."
    )
    logo = None
    if lab.logo is not None:
        where = Path(path).parent / Path(lab.logo).expanduser()
        missing = f"no such file (the logo that {source} names)"
        raw = read_bounded(where, LOGO_BYTES, "a logo image (PNG or JPEG)", missing=missing, binary=True)
        kind = next((m for magic, m in _MAGIC.items() if raw.startswith(magic)), None)
        if kind is None:
            raise ConfigError(
                f"the logo {lab.logo!r} is not a PNG or JPEG image", source=source, field="lab.logo"
            )
        logo = {
            "file": Path(lab.logo).name,
            "media_type": kind,
            "sha256": hashlib.sha256(raw).hexdigest(),
            "data_b64": base64.b64encode(raw).decode("ascii"),
        }
    return {
        "name": lab.name,
        "address": lab.address,
        "accreditation_id": lab.accreditation_id,
        "logo": logo,
    }


def lab_file(given: str | Path | None, configured: str | None) -> str | Path | None:
    """The lab identity file a run names: `given` (--lab), else $RIG_LAB, else the rig config's."""
    return given or os.environ.get(LAB_ENV) or configured
