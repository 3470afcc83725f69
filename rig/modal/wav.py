"""WAV recordings: one channel (a tap's ping) or two (hammer force, one response).

The RIFF chunks are walked here rather than by the standard library's `wave`, which in Python 3.11
reads neither IEEE-float samples nor WAVE_FORMAT_EXTENSIBLE headers (what phones and most audio
tools write). Accepted: PCM 16, 24 or 32 bit, IEEE float 32 or 64 bit, one or two channels. Each
refusal is one RecordingFormatError naming the file and the cause: not a WAV, truncated, a stream
whose size was never written, zero or absurd sample rate, more than two channels, an unsupported
sample format, non-finite samples. The file is read within MAX_BYTES (an endless file or a FIFO is
read no further). Samples are scaled to full scale 1.0.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.modal.errors import RecordingFormatError
from rig.modal.recording import MIN_SAMPLE_RATE_HZ, MIN_SAMPLES, Recording, read_recording_bytes

PCM, FLOAT, EXTENSIBLE = 1, 3, 0xFFFE
PCM_BITS = (16, 24, 32)
FLOAT_BITS = (32, 64)
MAX_CHANNELS = 2
MAX_SAMPLE_RATE_HZ = 1_000_000.0  # no microphone or DAQ card a lab uses samples faster
UNSET_SIZE = 0xFFFFFFFF  # a streaming writer's placeholder: the size was never written


@dataclass(frozen=True, eq=False)
class Wav:
    """A WAV file's samples, shape (samples, channels), scaled so that full scale is 1.0."""

    samples: np.ndarray
    rate_hz: float
    bits: int
    is_float: bool
    source: str = ""

    @property
    def channels(self) -> int:
        """Number of channels."""
        return int(self.samples.shape[1])

    @property
    def n(self) -> int:
        """Samples per channel."""
        return int(self.samples.shape[0])


def _chunks(raw: bytes, where: str) -> dict[bytes, bytes]:
    """The RIFF chunks of a WAVE file by id (the first of each id); refuses what is not one."""
    if len(raw) < 12 or raw[:4] not in (b"RIFF", b"RIFX") or raw[8:12] != b"WAVE":
        raise RecordingFormatError(f"{where}not a WAV file (no RIFF/WAVE header)")
    if raw[:4] == b"RIFX":
        raise RecordingFormatError(
            f"{where}a big-endian (RIFX) WAV file: export a standard little-endian WAV"
        )
    found: dict[bytes, bytes] = {}
    pos = 12
    while pos + 8 <= len(raw):
        cid, size = raw[pos : pos + 4], struct.unpack_from("<I", raw, pos + 4)[0]
        body = raw[pos + 8 : pos + 8 + size]
        if cid == b"data":
            if size == UNSET_SIZE or (size == 0 and pos + 8 < len(raw)):
                raise RecordingFormatError(
                    f"{where}the data chunk's size was never written (a recording stopped before it"
                    f" was saved, or a stream): save the recording as a finished file"
                )
            if len(body) < size:
                raise RecordingFormatError(
                    f"{where}truncated: the data chunk declares {size} bytes, the file holds {len(body)}"
                )
        found.setdefault(cid, body)
        pos += 8 + size + (size & 1)
    if b"fmt " not in found:
        raise RecordingFormatError(f"{where}truncated or malformed WAV: no format (fmt) chunk")
    if b"data" not in found:
        raise RecordingFormatError(f"{where}truncated or malformed WAV: no data chunk")
    return found


def _format(fmt: bytes, where: str) -> tuple[int, int, float, int, int]:
    """(format tag, channels, rate, block align, bits) from the fmt chunk, checked."""
    if len(fmt) < 16:
        raise RecordingFormatError(f"{where}malformed WAV: a format chunk of {len(fmt)} bytes (16 needed)")
    tag, channels, rate, _, align, bits = struct.unpack_from("<HHIIHH", fmt)
    if tag == EXTENSIBLE:
        if len(fmt) < 26:
            raise RecordingFormatError(
                f"{where}malformed WAV: an extensible format chunk without its sub-format"
            )
        tag = struct.unpack_from("<H", fmt, 24)[0]
    if channels == 0:
        raise RecordingFormatError(f"{where}a WAV with no channels")
    if channels > MAX_CHANNELS:
        raise RecordingFormatError(
            f"{where}{channels} channels: a tap recording has one, an impact test two (force, response)"
        )
    if not MIN_SAMPLE_RATE_HZ <= rate <= MAX_SAMPLE_RATE_HZ:
        raise RecordingFormatError(
            f"{where}a sample rate of {rate} Hz: a recording needs {MIN_SAMPLE_RATE_HZ:g}"
            f"-{MAX_SAMPLE_RATE_HZ:g} Hz"
        )
    if (tag, bits) not in [(PCM, b) for b in PCM_BITS] + [(FLOAT, b) for b in FLOAT_BITS]:
        kind = {PCM: "PCM", FLOAT: "float"}.get(tag, f"format {tag:#x}")
        raise RecordingFormatError(
            f"{where}{kind} samples of {bits} bit are not read: export PCM 16, 24 or 32 bit, or float 32 bit"
        )
    if align != channels * bits // 8:
        raise RecordingFormatError(
            f"{where}malformed WAV: block align {align} for {channels} channel(s) of {bits} bit"
        )
    return tag, channels, float(rate), align, bits


def _decode(data: bytes, tag: int, channels: int, bits: int) -> np.ndarray:
    """Samples as floats scaled to full scale 1.0, shape (n, channels)."""
    width = bits // 8
    if tag == FLOAT:
        x = np.frombuffer(data, dtype=f"<f{width}").astype(float)
    elif bits == 24:
        b = np.frombuffer(data, dtype=np.uint8).reshape(-1, 3).astype(np.int32)
        v = b[:, 0] | (b[:, 1] << 8) | (b[:, 2] << 16)
        x = (np.where(v >= 1 << 23, v - (1 << 24), v)).astype(float) / float(1 << 23)
    else:
        x = np.frombuffer(data, dtype=f"<i{width}").astype(float) / float(1 << (bits - 1))
    return x.reshape(-1, channels)


def read_wav(path: str | Path) -> Wav:
    """Read a WAV file (PCM 16/24/32 bit or float 32/64 bit, one or two channels), checked."""
    path = Path(path)
    where = f"{path}: "
    found = _chunks(read_recording_bytes(path), where)
    tag, channels, rate, align, bits = _format(found[b"fmt "], where)
    data = found[b"data"]
    if len(data) % align:
        raise RecordingFormatError(
            f"{where}truncated: the data ends inside a sample frame ({len(data)} bytes, frames of {align})"
        )
    samples = _decode(data, tag, channels, bits)
    if samples.shape[0] < MIN_SAMPLES:
        raise RecordingFormatError(
            f"{where}{samples.shape[0]} samples; a recording needs at least {MIN_SAMPLES}"
        )
    bad = np.flatnonzero(~np.isfinite(samples).all(axis=1))
    if bad.size:
        raise RecordingFormatError(
            f"{where}a non-finite sample at frame {int(bad[0])} ({bad.size} such frames)"
        )
    samples.setflags(write=False)
    return Wav(samples, rate, bits, tag == FLOAT, source=str(path))


def write_wav(path: str | Path, samples: np.ndarray, rate_hz: int, bits: int = 16) -> Path:
    """Write a PCM 16/24/32-bit (bits=-32: float 32) WAV from samples in [-1, 1], shape (n,) or (n, c)."""
    path = Path(path)
    x = np.asarray(samples, dtype=float)
    x = x.reshape(x.shape[0], -1)
    channels = x.shape[1]
    if bits == -32:
        tag, width, payload = FLOAT, 4, x.astype("<f4").tobytes()
    else:
        tag, width = PCM, bits // 8
        q = np.clip(np.round(x * (1 << (bits - 1))), -(1 << (bits - 1)), (1 << (bits - 1)) - 1).astype(
            np.int64
        )
        if bits == 24:
            v = (q & 0xFFFFFF).astype("<u4").tobytes()
            payload = b"".join(v[i : i + 3] for i in range(0, len(v), 4))
        else:
            payload = q.astype(f"<i{width}").tobytes()
    fmt = struct.pack(
        "<HHIIHH", tag, channels, rate_hz, rate_hz * channels * width, channels * width, width * 8
    )
    body = b"WAVE" + b"fmt " + struct.pack("<I", len(fmt)) + fmt + b"data" + struct.pack("<I", len(payload))
    path.write_bytes(b"RIFF" + struct.pack("<I", len(body) + len(payload)) + body + payload)
    return path


def impact_recording(wav: Wav) -> Recording:
    """A two-channel WAV (channel 1 the hammer force, channel 2 one response) as a Recording.

    WAV carries no units: force and response are in full-scale units, which scales the FRF but not
    its frequencies or damping. With one response the two accelerometer columns are the same signal
    and `responses` is 1: the magnitude ratio cannot tell hoop from bending (the analysis then uses
    the output-only rule, rig.modal.tap).
    """
    if wav.channels != 2:
        raise RecordingFormatError(
            f"{wav.source}: {wav.channels} channel(s): an impact test in WAV needs two (force, response);"
            f" a one-channel tap recording is read by `rig modal tap`"
        )
    t = np.arange(wav.n, dtype=float) / wav.rate_hz
    force, response = wav.samples[:, 0], wav.samples[:, 1]
    rec = Recording.build(t, force, response, response, source=wav.source)
    return Recording(rec.time_s, rec.force, rec.accel1, rec.accel2, rec.source, rec.step_s, responses=1)
