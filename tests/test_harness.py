"""The harness itself: the plugins load, and the committed captures are what
the generator makes."""
import re
import subprocess

from conftest import BUILD, ROOT, _world_dir


def test_eglink_plugin_listed(tshark):
    out = tshark.run(["-G", "plugins"]).stdout
    rows = [line.split("\t") for line in out.splitlines()]
    eglink = [r for r in rows if r[0].strip() == "vrshark.so"]
    assert eglink, "vrshark.so not in tshark -G plugins"
    assert eglink[0][2] == "dissector"
    assert eglink[0][3].startswith(str(BUILD / "wsplugins"))


def test_captures_match_generator():
    proc = subprocess.run([str(ROOT / "tools" / "gen-captures"), "--check"],
                          capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def lua_plugins_listed(tshark):
    """{name: (version, path)} of the Lua scripts `tshark -G plugins` lists."""
    out = tshark.run(["-G", "plugins"]).stdout
    listed = {}
    for line in out.splitlines():
        cols = [c.strip() for c in line.split("\t")]
        if len(cols) >= 3 and cols[2].lower() == "lua script":
            listed[cols[0]] = (cols[1], cols[3] if len(cols) > 3 else "")
    return listed


def test_every_lua_plugin_loads_with_version(tshark):
    """Each .lua file under lua/ is a plugin: it loads without error and gives
    the project's version (set_plugin_info)."""
    listed = lua_plugins_listed(tshark)
    version = re.search(r"project\(vrshark VERSION ([0-9.]+)", (ROOT / "CMakeLists.txt").read_text()).group(1)
    for p in sorted((ROOT / "lua").glob("*.lua")):
        assert p.name in listed, "not loaded: %s" % p.name
        assert listed[p.name][0] == version, (p.name, listed[p.name])


def test_helper_modules_are_not_plugins(tshark):
    """The shared modules (lua/vrshark/*.luam) are never run as plugins, and no
    .lua file hides in a subfolder (Wireshark would run it)."""
    listed = lua_plugins_listed(tshark)
    modules = sorted(p.name for p in (ROOT / "lua" / "vrshark").iterdir())
    assert modules and all(m.endswith(".luam") for m in modules), modules
    assert not [m for m in modules if m in listed or m.replace(".luam", ".lua") in listed]
    assert set(listed) <= {p.name for p in (ROOT / "lua").glob("*.lua")} | {"selftest.lua"}


def test_a_checkout_in_a_private_folder_is_reachable():
    """git clone . "$(mktemp -d)/p" as root puts the checkout in a mode-700
    folder the test user (uid 65534) cannot enter: tools/reachable (run by
    tools/tshark, tools/test, tools/screenshots) gives it search permission,
    so the plugins load and the captures open, and says so."""
    import os
    import shutil
    if os.getuid() != 0:
        return      # only root drops to another user
    base = _world_dir("vrshark-private-")    # reachable itself: only the private folder is not
    private = base / "private"
    (private / "p" / "tools").mkdir(parents=True)
    private.chmod(0o700)
    shutil.copy(ROOT / "tools" / "reachable", private / "p" / "tools" / "reachable")
    proc = subprocess.run([str(private / "p" / "tools" / "reachable")], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert private.stat().st_mode & 0o777 == 0o701
    assert proc.stderr == ("tools/reachable: %s: search permission for others added (the test user must "
                           "reach the checkout)\n" % private)
    again = subprocess.run([str(private / "p" / "tools" / "reachable")], capture_output=True, text=True)
    assert again.stderr == ""
    shutil.rmtree(base)


# --- shared runs (tests/tshark_runs.py) ----------------------------------------

def test_union_answers_as_a_run_of_its_own(tshark, capture_file, monkeypatch):
    """fields() picked from the union run is what tshark prints for the request
    alone: every occurrence setting, an aggregator, a separator, booleans,
    absent fields, a filter and two passes."""
    import tshark_runs
    cap = capture_file("eglink_analysis_vrpo_split.pcap")
    requests = [
        (["eglink.type", "eglink.serial", "_ws.col.Info"], {}),
        (["frame.number", "_ws.expert.message", "eglink.crc.status"], {"aggregator": "|", "occurrence": "a"}),
        (["eglink.fragment", "eglink.analysis.vrpo_gap"], {"occurrence": "f", "two_pass": True}),
        (["eglink.fragment"], {"occurrence": "l", "display_filter": "eglink.type == \"VRPO\""}),
        (["eglink.fragment", "eglink.bu_state"], {"occurrence": "f", "sep": ";"}),
    ]
    assert tshark_runs.union_may_answer(cap, "a")
    shared = [tshark.fields(cap, names, **kw) for names, kw in requests]
    monkeypatch.setattr(tshark_runs, "EXACT", True)
    alone = [tshark.fields(cap, names, **kw) for names, kw in requests]
    assert shared == alone
    assert any(cell for rows in alone for row in rows for cell in row[1:])


def test_run_key_follows_the_files_it_names(work_dir):
    """A capture written anew (another size or time) is another run; the
    per-worker name of the empty configuration folder is not."""
    import tshark_runs
    cap = work_dir / "x.pcap"
    cap.write_bytes(b"1")
    conf_a, conf_b = work_dir / "a", work_dir / "b"
    conf_a.mkdir()
    conf_b.mkdir()
    key = tshark_runs.run_key(["-r", str(cap)], {"WIRESHARK_CONFIG_DIR": str(conf_a)})
    assert key == tshark_runs.run_key(["-r", str(cap)], {"WIRESHARK_CONFIG_DIR": str(conf_b),
                                                         "PYTEST_XDIST_WORKER": "gw1"})
    cap.write_bytes(b"22")
    assert key != tshark_runs.run_key(["-r", str(cap)], {"WIRESHARK_CONFIG_DIR": str(conf_a)})
    (conf_b / "preferences").write_text("x")
    assert key != tshark_runs.run_key(["-r", str(cap)], {"WIRESHARK_CONFIG_DIR": str(conf_b)})


def test_store_makes_a_run_once(work_dir):
    import tshark_runs
    store = tshark_runs.RunStore(work_dir)
    made = []

    def make():
        made.append(1)
        return subprocess.CompletedProcess(["x"], 0, "out", "err")
    first = store.get("key", make)
    again = store.get("key", make)
    assert made == [1]
    assert (again.returncode, again.stdout, again.stderr) == (first.returncode, "out", "err")
