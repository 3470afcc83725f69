"""The ball-law file (BALL.json): a ball's contact constants fitted to CCOR tests, and their source.

Written by `rig model fit-ball`, read by every command that takes `--ball`. The ball's constants
m1, k1, c1, a and b replace the paper's defaults; the barrel's m2 and c2 are not the ball's and
stay as each command has them. `BallLaw.load` refuses, in one line naming the file, anything that
is not such a file (missing, binary, huge, malformed JSON, wrong kind, bad values).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from rig.core.errors import ConfigError
from rig.core.files import parse_json, read_bounded
from rig.physics.params import DEFAULT_PARAMS, CollisionParams, check_physical

KIND = "rig-ball-law"
FORMAT = 1
BALL_NAMES = ("m1", "k1", "c1", "a", "b")  # the constants a ball file sets
MAX_BYTES = 4_000_000  # a ball file is a few kB; anything this large is not one


class BallProvenance(BaseModel):
    """Where the ball law came from."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    data_file: str
    data_sha256: str
    lot: str | None = None
    runs: list[str] = []  # the store's ball-test runs the points come from (--db); empty for a file
    n_points: int = Field(ge=1)
    n_balls: int = Field(ge=1)
    n_speeds: int = Field(ge=1)
    speed_min_m_s: float
    speed_max_m_s: float
    created_utc: str
    software: str
    fixed: dict[str, str] = {}  # a constant not fitted -> where its value comes from


class BallLaw(BaseModel):
    """A fitted ball: its constants, the variant, the covariance of the fitted ones, and the source."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)

    kind: Literal["rig-ball-law"] = "rig-ball-law"
    format: Literal[1] = 1
    constants: dict[str, float]  # m1, k1, c1, a, b: what the model solves with
    variant: str
    parameters: dict[str, float]  # the fitted ones, in the variant's order
    uncertainty: dict[str, float]  # one sigma of each fitted one
    covariance: list[list[float]]
    correlation_ab: float | None = None
    scatter: float  # residual scatter of CCOR (unweighted RMS about the fit, n - p degrees of freedom)
    loo_rmse: float
    dof: int
    weighting: str
    selection: str
    variants: list[dict[str, Any]] = []
    points: list[dict[str, Any]] = []
    notes: list[str] = []
    provenance: BallProvenance

    @model_validator(mode="after")
    def _consistent(self) -> BallLaw:
        if set(self.constants) != set(BALL_NAMES):
            raise ValueError(f"constants must be exactly {', '.join(BALL_NAMES)}")
        check_physical(DEFAULT_PARAMS.model_copy(update=self.constants))
        CollisionParams.build(**self.constants)
        unknown = [n for n in self.parameters if n not in BALL_NAMES]
        if unknown:
            raise ValueError(f"fitted parameter(s) {', '.join(unknown)} are not the ball's")
        for n, v in self.parameters.items():
            if abs(v - self.constants[n]) > 1e-9 * max(abs(v), 1.0):
                raise ValueError(f"fitted {n} = {v:g} differs from the constant {self.constants[n]:g}")
        p = len(self.parameters)
        if len(self.covariance) != p or any(len(r) != p for r in self.covariance):
            raise ValueError(f"covariance must be {p} x {p}")
        return self

    @property
    def params(self) -> CollisionParams:
        """The paper's constants with the ball's m1, k1, c1, a and b in place."""
        return DEFAULT_PARAMS.model_copy(update=self.constants)

    @property
    def lot(self) -> str | None:
        """The ball lot the data came from, if known."""
        return self.provenance.lot

    def apply(self, params: CollisionParams) -> CollisionParams:
        """`params` with the ball's constants replacing its m1, k1, c1, a and b (m2, c2 kept)."""
        return params.model_copy(update=self.constants)

    def to_json(self) -> str:
        """The file's text (canonical enough to hash: fixed key order, two-space indent)."""
        return json.dumps(self.model_dump(mode="json"), indent=2, allow_nan=False) + "\n"

    def save(self, path: str | Path) -> Path:
        """Write atomically (a temporary file beside it, then a rename)."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
        try:
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(self.to_json())
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def load(cls, path: str | Path) -> BallLaw:
        """Read and validate a ball file; ConfigError names the file and the first problem."""
        return cls.read(path)[0]

    @classmethod
    def read(cls, path: str | Path) -> tuple[BallLaw, str]:
        """The ball law and the sha256 of the file's bytes (what a calibration records)."""
        law, raw = cls.read_file(path)
        return law, hashlib.sha256(raw).hexdigest()

    @classmethod
    def read_file(cls, path: str | Path) -> tuple[BallLaw, bytes]:
        """The ball law and the file's bytes, read once (bounded); ConfigError as `parse_bytes`."""
        raw = read_bounded(Path(path), MAX_BYTES, "a ball file")
        return cls.parse_bytes(raw, str(path)), raw

    @classmethod
    def parse_text(cls, text: str, source: str = "recorded ball law") -> BallLaw:
        """A ball law from a ball file's text (as a store records it); ConfigError as `read`."""
        raw = text.encode("utf-8")
        if len(raw) > MAX_BYTES:
            raise ConfigError(f"not a ball file: larger than {MAX_BYTES} bytes", source=source)
        return cls.parse_bytes(raw, source)

    @classmethod
    def parse_bytes(cls, raw: bytes, source: str) -> BallLaw:
        """Validate a ball file's bytes; ConfigError names `source` and the first problem."""
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ConfigError(f"not a ball file: not UTF-8 text (byte {exc.start})", source=source) from None
        data = parse_json(text, source, "a ball file")
        if not isinstance(data, dict) or data.get("kind") != KIND:
            raise ConfigError(f"not a ball file: its kind is not {KIND!r}", source=source)
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            first = exc.errors()[0]
            field = ".".join(str(p) for p in first["loc"]) or "file"
            raise ConfigError(first["msg"], source=source, field=field) from None
        except ConfigError as exc:
            raise ConfigError(exc.reason, source=source, field=exc.field) from None
        except ValueError as exc:  # a ParameterError from the constants' ranges
            raise ConfigError(str(exc), source=source, field="constants") from None


def ball_record(law: BallLaw, sha256: str, path: str | Path | None = None) -> dict[str, Any]:
    """What a calibration records of the ball it was made with."""
    return {
        "file": None if path is None else Path(path).name,
        "sha256": sha256,
        "lot": law.lot,
        "variant": law.variant,
        "constants": dict(law.constants),
    }


__all__ = ["BALL_NAMES", "KIND", "BallLaw", "BallProvenance", "ball_record"]
