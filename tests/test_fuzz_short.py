"""Fuzzing: a short tools/fuzz run over every capture (mutated, under ASan and
UBSan) must find nothing, and the fuzzer must catch bugs injected on purpose.

VRSHARK_SKIP_FUZZ=1 skips these (they take about a minute and a half).
"""
import json
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

from conftest import ROOT

pytestmark = pytest.mark.skipif(os.environ.get("VRSHARK_SKIP_FUZZ", "") not in ("", "0"),
                                reason="VRSHARK_SKIP_FUZZ is set")

FUZZ = str(ROOT / "tools" / "fuzz")


@pytest.fixture
def out_dir():
    path = Path(tempfile.mkdtemp(prefix="vrshark-fuzz-"))
    path.chmod(0o777)
    yield path
    shutil.rmtree(path, ignore_errors=True)


def test_fuzz_short_run_finds_nothing(out_dir):
    proc = subprocess.run([FUZZ, "--seconds", "50", "--out", str(out_dir)],
                          capture_output=True, text=True, timeout=900)
    report = proc.stdout + proc.stderr
    kept = sorted(p.name for p in out_dir.glob("fail-*"))
    assert proc.returncode == 0, "tools/fuzz failed; kept %s\n%s" % (kept, report[-6000:])
    summary = json.loads((out_dir / "last-run.json").read_text())
    assert summary["result"] == "PASS"
    assert summary["failures"] == []
    assert summary["captures"] == len(list((ROOT / "captures").glob("*.pcap*")))
    # Every capture is checked unmutated (one run), and mutated ones ran
    # (two tshark runs each).
    assert summary["mutated"] >= 5, report
    assert summary["runs"] >= summary["captures"] + 2 * summary["mutated"]
    assert re.search(r"PASS: %d mutated captures" % summary["mutated"], report)


def test_fuzz_catches_injected_bugs(out_dir):
    """A deliberately broken C plugin (heap overflow, oversized shift, failed
    DISSECTOR_ASSERT) and Lua postdissector (error()) are fuzzed; each kind must
    be caught and the kept capture must fail again on replay."""
    proc = subprocess.run([FUZZ, "--self-test", "--seed", "1", "--out", str(out_dir)],
                          capture_output=True, text=True, timeout=900)
    report = proc.stdout + proc.stderr
    assert proc.returncode == 0, report[-6000:]
    caught = re.search(r"caught: (.*)", report).group(1).split(", ")
    assert {"asan", "ubsan", "lua-error", "dissector-bug"} <= set(caught), report
    assert "fails again" in report
    logs = list((out_dir / "selftest").glob("fail-*.txt"))
    assert any("heap-buffer-overflow" in p.read_text() for p in logs)
    assert any("shift exponent" in p.read_text() for p in logs)
    assert any("failed assertion" in p.read_text() for p in logs)
    scripts = list((out_dir / "selftest").glob("fail-*.sh"))
    assert len(scripts) == len(logs) > 0
