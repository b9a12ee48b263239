"""LICENSE, CITATION.cff and CHANGELOG.md agree with pyproject.toml, and CITATION.cff is valid
Citation File Format 1.2.0 (issue 38).

The check is ``cffconvert --validate``'s: the file against the CFF 1.2.0 JSON schema, vendored
here from cffconvert 2.0.0 (``cff-schema-1.2.0.json``), since cffconvert pins an old jsonschema.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import jsonschema
import yaml

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[2]
PROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]


def _cff() -> dict:
    # CFF is YAML; dates are strings in the schema, so keep them as written
    loader = yaml.SafeLoader
    return yaml.load((ROOT / "CITATION.cff").read_text(), Loader=loader)


def test_citation_cff_is_valid_cff_1_2_0():
    data = _cff()
    if not isinstance(data.get("date-released"), str):
        data["date-released"] = str(data["date-released"])
    schema = json.loads((Path(__file__).parent / "cff-schema-1.2.0.json").read_text())
    validator = jsonschema.Draft7Validator(schema)
    assert [e.message for e in validator.iter_errors(data)] == []
    broken = {k: v for k, v in data.items() if k != "cff-version"}  # the schema does check
    assert any("cff-version" in e.message for e in validator.iter_errors(broken))


def test_citation_and_changelog_name_this_version():
    assert _cff()["version"] == PROJECT["version"]
    assert _cff()["license"] == PROJECT["license"] == "MIT"
    first = re.search(r"^## (\S+)", (ROOT / "CHANGELOG.md").read_text(), flags=re.M)
    assert first and first.group(1) == PROJECT["version"]
    assert f"version = {{{PROJECT['version']}}}" in (ROOT / "README.md").read_text()


def test_the_licence_is_mit_for_the_authors():
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("MIT License")
    assert "Copyright (c) 2026 the pacam_render authors" in text
