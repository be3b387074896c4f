"""schemas/openapi.yaml through the three tools API users run on it: swagger-parser's validate
(every $ref dereferenced, the result checked against the OpenAPI 3.1 schema), Redocly CLI's lint
with the recommended rules (redocly.yaml) and Spectral's lint with its OpenAPI rules
(.spectral.yaml), each at 0 errors and 0 warnings. All come from npm (tests/js, pinned by its
package.json and package-lock.json: swagger-parser 10.1.1, Redocly CLI 1.34.5, Spectral CLI
6.16.3) and run on Node.js; scripts/test.sh installs nodejs and npm. Redocly CLI 2.x needs Node.js
20.19, which Debian 12 does not have; the document passes it too (docs/api.md says how)."""

import json
import os
import shutil
import subprocess

import pytest

from conftest import ROOT, npm_tool

JS_TOOL = os.path.join(ROOT, "tests", "js")
OPENAPI = os.path.join(ROOT, "schemas", "openapi.yaml")
# Redocly CLI would send usage data and ask the npm registry for a newer version: neither here.
NODE_ENV = dict(os.environ, REDOCLY_TELEMETRY="off", REDOCLY_SUPPRESS_UPDATE_NOTICE="true")


@pytest.fixture(scope="module")
def tools():
    """tests/js with its node_modules (npm ci into the build directory once per lock file)."""
    return npm_tool(JS_TOOL, "js-tools")


def swagger_parser_validate(work, path):
    return subprocess.run(["node", os.path.join(work, "validate_openapi.mjs"), path],
                          capture_output=True, text=True, timeout=120, env=NODE_ENV)


def redocly_lint(work, path):
    """Redocly's totals ({errors, warnings, ignored}) and problems for the document at `path`."""
    out = subprocess.run([os.path.join(work, "node_modules", ".bin", "redocly"), "lint",
                          "--config", os.path.join(ROOT, "redocly.yaml"), "--format=json", path],
                         capture_output=True, text=True, timeout=120, env=NODE_ENV, cwd=ROOT)
    report = json.loads(out.stdout)
    return report["totals"], report["problems"]


def spectral_lint(work, path):
    """Spectral's results (each with its code and severity: 0 error, 1 warning, 2 info, 3 hint)."""
    out = subprocess.run([os.path.join(work, "node_modules", ".bin", "spectral"), "lint",
                          "--ruleset", os.path.join(ROOT, ".spectral.yaml"), "--format", "json",
                          "--quiet", path],
                         capture_output=True, text=True, timeout=120, env=NODE_ENV, cwd=ROOT)
    text = out.stdout[out.stdout.index("["):out.stdout.rindex("]") + 1]
    return json.loads(text)


def test_swagger_parser_validates_the_document(tools):
    out = swagger_parser_validate(tools, OPENAPI)
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith("ok: npfkct planning server"), out.stdout


def test_redocly_lint_has_no_errors_and_no_warnings(tools):
    totals, problems = redocly_lint(tools, OPENAPI)
    assert totals["errors"] == 0 and totals["warnings"] == 0, json.dumps(problems, indent=1)
    assert problems == [], json.dumps(problems, indent=1)


def test_spectral_lint_has_no_errors_and_no_warnings(tools):
    results = spectral_lint(tools, OPENAPI)
    assert results == [], json.dumps(results, indent=1)


def test_the_tools_refuse_what_the_issue_found(tools, tmp_path):
    """The faults the document had (a top-level $ref with siblings, an operation without a
    summary) fail the tools: the checks above are not vacuous."""
    broken = tmp_path / "schemas"
    shutil.copytree(os.path.join(ROOT, "schemas"), broken)
    session = json.loads((broken / "session.schema.json").read_text())
    session["$ref"] = session.pop("allOf")[0]["$ref"]
    (broken / "session.schema.json").write_text(json.dumps(session))
    assert swagger_parser_validate(tools, str(broken / "openapi.yaml")).returncode != 0
    text = (broken / "openapi.yaml").read_text()
    summary = "      summary: Get a session (its state, step, pending action and planner).\n"
    assert summary in text
    (broken / "openapi.yaml").write_text(text.replace(summary, ""))
    totals, problems = redocly_lint(tools, str(broken / "openapi.yaml"))
    assert totals["errors"] >= 1
    assert "operation-summary" in {p["ruleId"] for p in problems}
    # An operation without tags or a description, and a document without a contact: Spectral's
    # warnings.
    text = (broken / "openapi.yaml").read_text()
    for line in ("      tags: [planners]\n", "  contact:\n    name: npfkct maintainers\n"):
        assert line in text
        text = text.replace(line, "")
    (broken / "openapi.yaml").write_text(text)
    codes = {r["code"] for r in spectral_lint(tools, str(broken / "openapi.yaml"))}
    assert {"operation-tags", "info-contact"} <= codes, codes
