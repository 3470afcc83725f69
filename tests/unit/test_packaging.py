"""The package metadata that `make install` builds from: nothing setuptools warns about."""

from __future__ import annotations

import tomllib
from pathlib import Path

from packaging.licenses import canonicalize_license_expression
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[2]


def test_the_license_is_an_spdx_expression_that_the_required_setuptools_reads() -> None:
    """A license table is deprecated (setuptools printed the warning three times per install); the
    SPDX string form needs setuptools 77 or newer in the build."""
    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    license_ = data["project"]["license"]
    assert isinstance(license_, str), license_
    assert canonicalize_license_expression(license_) == license_
    (setuptools,) = [Requirement(r) for r in data["build-system"]["requires"] if r.startswith("setuptools")]
    floor = [s.version for s in setuptools.specifier if s.operator == ">="]
    assert floor and int(floor[0].split(".")[0]) >= 77, setuptools
