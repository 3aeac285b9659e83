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


def test_every_lua_file_loads(tshark):
    """Each .lua file under lua/ is run as a plugin at start-up (modules too)
    and loads without error."""
    out = tshark.run(["-G", "plugins"]).stdout
    loaded = {line.split("\t")[0].strip() for line in out.splitlines() if "\tlua script\t" in line.lower()}
    expected = {p.name for p in (ROOT / "lua").rglob("*.lua")}
    assert expected <= loaded, "not loaded: %s" % sorted(expected - loaded)
