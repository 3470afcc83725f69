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
        super().__init__(f"{name} = {value!r}: {reason}")

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
