"""The harness itself: the plugins load, and the committed captures are what
the generator makes."""
import subprocess

from conftest import BUILD, ROOT


def test_eglink_plugin_listed(tshark):
    out = tshark.run(["-G", "plugins"]).stdout
    rows = [line.split("\t") for line in out.splitlines()]
    eglink = [r for r in rows if r[0].strip() == "eglink.so"]
    assert eglink, "eglink.so not in tshark -G plugins"
    assert eglink[0][2] == "dissector"
    assert eglink[0][3].startswith(str(BUILD / "wsplugins"))


def test_captures_match_generator():
    proc = subprocess.run([str(ROOT / "tools" / "gen-captures"), "--check"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
