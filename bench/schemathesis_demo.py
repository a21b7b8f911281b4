"""schemathesis with every check against `hvcb demo` as a new user runs it (issue 44 item 7): no
failure but the documented throttle (429) and content refused in words (422), no response over
10 s, no network error.

Starts the demo (fresh data folder, its history playing), runs the schemathesis CLI against it
with its admin key, ``--checks all``, ``--request-timeout 10``, the same expected statuses as
tests/service/test_schemathesis.py, and writes bench/results/schemathesis_demo.json (cases,
failures by check and operation, the slowest responses).

    flock /tmp/hvcb-heavy.lock nice -n 5 .venv/bin/python bench/schemathesis_demo.py
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from demo_common import ROOT, Demo  # noqa: E402

CONFIG = """
[checks.positive_data_acceptance]
expected-statuses = ["2xx", "3xx", "401", "403", "404", "409", "410", "429"]

[[operations]]
include-operation-id = ["create_breaker", "upload_capture", "request_breaker_diagnosis", "breaker_report", "request_report",
                        "operations_csv", "alarms_csv"]
checks.positive_data_acceptance.expected-statuses = ["2xx", "401", "403", "404", "409", "410", "422", "429"]
"""


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--examples", type=int, default=30)
    args = ap.parse_args()
    out = {"uptime_before": os.popen("uptime").read().strip(), "examples_per_operation": args.examples}
    demo = Demo().start()
    try:
        with tempfile.TemporaryDirectory() as where:
            (Path(where) / "schemathesis.toml").write_text(CONFIG)
            cmd = [sys.executable, "-m", "schemathesis.cli", "--config-file", f"{where}/schemathesis.toml", "run",
                   f"{demo.url}/openapi.json", "--checks", "all", "--max-examples", str(args.examples),
                   "--generation-deterministic", "--workers", "1", "--header", f"X-API-Key: {demo.key}",
                   "--no-color", "--request-timeout", "10", "--report", "json",
                   "--report-json-path", f"{where}/report.json"]
            run = subprocess.run(cmd, cwd=where, capture_output=True, text=True, timeout=1500)
            report = json.loads((Path(where) / "report.json").read_text()) if (Path(where) / "report.json").exists() else {}
    finally:
        demo.stop()
    text = run.stdout
    out["exit_code"] = run.returncode
    out["test_cases"] = report.get("test_cases")
    out["operations"] = report.get("operations")
    out["errors"] = report.get("errors")
    failures = text[text.find("FAILURES"):text.find("WARNINGS")] if "FAILURES" in text else ""
    out["failure_headers"] = re.findall(r"_{3,} (.+?) _{3,}", failures)
    out["failure_checks"] = sorted(set(re.findall(r"- (ST\d+ [^\n]+)", failures)))
    out["statuses_in_failures"] = sorted(set(re.findall(r"\[(\d{3})\]", failures)))
    out["summary_tail"] = text[-1500:]
    out["uptime_after"] = os.popen("uptime").read().strip()
    (ROOT / "bench" / "results" / "schemathesis_demo.json").write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps({k: v for k, v in out.items() if k != "summary_tail"}, indent=1))
    print(out["summary_tail"])
    return 0


if __name__ == "__main__":
    sys.exit(main())
