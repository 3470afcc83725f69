"""The project's error hierarchy: every failure names its cause."""

from __future__ import annotations


class RigError(Exception):
    """Base class of every error the controller raises on purpose."""


class ParameterError(RigError, ValueError):
    """A parameter value is refused; the message names the parameter."""

    def __init__(self, name: str, value: object, reason: str) -> None:
        self.name = name
        self.value = value
        self.reason = reason
        super().__init__(f"{name} = {shown(value, 80)}: {reason}")

    @classmethod
    def from_validation(cls, exc: Exception) -> ParameterError:
        """Turn a pydantic ValidationError into one ParameterError naming the first bad field."""
        errors = getattr(exc, "errors", None)
        if callable(errors):
            first = errors()[0]
            name = ".".join(str(p) for p in first.get("loc", ())) or "parameters"
            return cls(name, first.get("input"), first.get("msg", str(exc)))
        return cls("parameters", None, str(exc))


class SolverError(RigError, RuntimeError):
    """A numerical solve failed; the message says where and why."""


class DeviceError(RigError):
    """A device failed to do what was asked; `device` names it."""

    def __init__(self, device: str, message: str) -> None:
        self.device = device
        super().__init__(f"{device}: {message}")


class DeviceTimeout(DeviceError):
    """No (complete) reply within the time allowed."""


class DeviceRefused(DeviceError):
    """The device answered with an error reply."""

    def __init__(self, device: str, command: str, code: str, text: str) -> None:
        self.command, self.code, self.text = command, code, text
        super().__init__(device, f"refused {command}: {code} {text}".rstrip())


class NotSent(DeviceRefused):
    """The driver refused a command the device's state table forbids now, without sending it."""

    def __init__(self, device: str, command: str, reason: str) -> None:
        self.command, self.code, self.text = command, "STATE", reason
        DeviceError.__init__(self, device, f"{command} not sent: {reason}")


class GarbledReply(DeviceError):
    """A line that failed its CRC, framing or grammar, or a reply missing a field."""


class UnexpectedMessage(DeviceError):
    """A well-formed message that makes no sense now (e.g. an unknown event)."""


class DeviceGone(DeviceError):
    """The port vanished or could not be opened (unplugged, wrong path, simulator stopped)."""


class SafetyRefusal(DeviceError):
    """The controller refused to arm or fire: an interlock or the state table says no."""


class ConfigError(RigError, ValueError):
    """A configuration file or value is refused; the message names the file and the field."""

    def __init__(self, reason: str, source: str = "", field: str = "") -> None:
        self.reason, self.source, self.field = reason, source, field
        super().__init__(": ".join(part for part in (source, field, reason) if part))


class StoreError(RigError):
    """The run records (rig.store) failed; the message names the file or the record."""


class StoreFileError(StoreError):
    """A file is not a usable store: missing, unreadable, not SQLite, foreign or too new."""


class RecordRefused(StoreError, ValueError):
    """An entry, payload, kind or status the store will not write; the message says why."""


class UnknownRecord(StoreError, LookupError):
    """No run or bat with that id; the message lists ids that do exist."""


def shown(value: object, limit: int = 60) -> str:
    """A value as a message quotes it: its repr, cut to `limit` characters (a hostile file's
    megabyte-long cell must not make a megabyte-long message)."""
    text = repr(value)
    return text if len(text) <= limit else f"{text[: limit - 4]}...{text[-1]}"


def listed(names: list[str], most: int = 6) -> str:
    """Names as a message lists them: each shown, at most `most`, then how many more."""
    out = ", ".join(n if len(n) <= 40 and n.isprintable() else shown(n, 40) for n in names[:most])
    return out if len(names) <= most else f"{out} and {len(names) - most} more"
