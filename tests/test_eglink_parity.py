"""The Lua EG-Link (lua/eglink.lua, vrshark/eglink_analysis.luam), used where
the C plugin is not loaded, decodes as the C plugin (plugins/vrshark): the
eglink layer of `-T json` (every field, value and expert info, analysis
included), `-z expert` and the Protocol and Info columns are the same, in
one pass and two (-2), for every project capture that holds EG-Link and for
random valid and corrupted EG-Link sessions (hypothesis).

What cannot be the same (docs/eglink.md, "EG-Link in Lua"): a Lua protocol's
short name is its name in capitals, so `-z expert` files the Lua findings
under "EGLINK" where the C plugin's read "EG-Link" (compared with that
name mapped), and the C plugin's statistics tree (-z eglink,tree) is C only.
"""
import copy
import json
import os
import random
import re

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from conftest import CAPTURES, ROOT
from eglink_testlib import gen
from tools.capgen.frames import udp_frame
from tools.capgen.pcap import Capture

# Without the analysis module the Lua EG-Link decodes the packets only.
pytestmark = pytest.mark.skipif(not (ROOT / "lua" / "vrshark" / "eglink_analysis.luam").exists(),
                                reason="the Lua EG-Link analysis (lua/vrshark/eglink_analysis.luam) is not here")

SETTINGS = dict(deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])
_runs = iter(range(10 ** 6))  # a new file name per example (tshark's results are cached by arguments)

EGLINK_IDS = re.compile(rb"VR[PCA][IO]")


def _holds_eglink(path):
    return EGLINK_IDS.search(path.read_bytes()) is not None


# Every capture with an EG-Link packet ID in it (the test checks that the C
# plugin decodes EG-Link in it).
CAPTURE_NAMES = sorted(p.name for p in CAPTURES.glob("*.pcap") if _holds_eglink(p))


@pytest.fixture(scope="module")
def c_tshark(tshark):
    t = copy.copy(tshark)
    t.env = {k: v for k, v in tshark.env.items() if k != "VRSHARK_NO_C_PLUGIN"}
    t._cache = {}
    return t


@pytest.fixture(scope="module")
def lua_tshark(tshark):
    t = copy.copy(tshark)
    t.env = dict(tshark.env, VRSHARK_NO_C_PLUGIN="1")
    t._cache = {}
    return t


EXPERT_ROW = re.compile(r"^(\s+\d+\s+\S+\s+)(\S+)(\s+.*)$")


def decode(t, capture, two_pass, prefs=None):
    """(eglink layers, the Protocol and Info columns followed by -z expert) of
    a capture, as compared."""
    opts = t._opts(prefs=prefs, two_pass=two_pass)
    out = t.run(["-n", "-r", str(capture)] + opts + ["-T", "json", "--no-duplicate-keys", "-j", "eglink"]).stdout
    layers = [(p["_source"]["layers"].get("frame", {}).get("frame.number"), p["_source"]["layers"].get("eglink"))
              for p in json.loads(out or "[]")]
    text = []
    for line in t.run(["-n", "-r", str(capture)] + opts + [
            "-T", "fields", "-e", "frame.number", "-e", "_ws.col.Protocol", "-e", "_ws.col.Info",
            "-z", "expert"]).stdout.splitlines():
        m = EXPERT_ROW.match(line)
        if m:
            # (the Lua protocol's short name is EGLINK; the columns are as wide as it)
            line = " ".join((m.group(1) + ("EG-Link" if m.group(2) == "EGLINK" else m.group(2)) + m.group(3)).split())
        text.append(line)
    return layers, text


def assert_same(c_tshark, lua_tshark, capture, two_pass, prefs=None):
    c_layers, c_text = decode(c_tshark, capture, two_pass, prefs)
    l_layers, l_text = decode(lua_tshark, capture, two_pass, prefs)
    for (frame, c), (_, lua) in zip(c_layers, l_layers):
        assert lua == c, "frame %s of %s (-2: %s): the Lua eglink layer differs\nC:   %s\nLua: %s" % (
            frame, capture.name, two_pass, json.dumps(c, sort_keys=True), json.dumps(lua, sort_keys=True))
    assert len(l_layers) == len(c_layers)
    assert l_text == c_text, "columns or -z expert of %s differ" % capture.name
    return c_layers


@pytest.mark.parametrize("two_pass", [False, True])
@pytest.mark.parametrize("name", CAPTURE_NAMES)
def test_capture_parity(c_tshark, lua_tshark, name, two_pass):
    layers = assert_same(c_tshark, lua_tshark, CAPTURES / name, two_pass)
    assert any(layer for _, layer in layers), "no EG-Link decoded in %s" % name


# The preferences of the TS-0006 rules (resend tolerance, burst spread) and
# the analysis thresholds they meet, away from their defaults.
RULE_PREFS = [{"eglink.resend_tolerance_ms": "0", "eglink.burst_spread_ms": "0"},
              {"eglink.resend_tolerance_ms": "150", "eglink.burst_spread_ms": "1000",
               "eglink.vrpo_gap_ms": "100", "eglink.vrco_ack_timeout_ms": "250"},
              {"eglink.periodic_size": "976", "eglink.reassemble_vrpo": "FALSE"}]


@pytest.mark.parametrize("prefs", RULE_PREFS, ids=["tight", "loose", "sized"])
@pytest.mark.parametrize("name", ["eglink_analysis_spec_rules.pcap", "eglink_analysis_vrco_unacked.pcap",
                                  "eglink_analysis_vrpo_split.pcap"])
def test_rule_prefs_parity(c_tshark, lua_tshark, name, prefs):
    """TS-0006 4.2, 5.1.2 to 5.1.4: eglink.resend_tolerance_ms and
    eglink.burst_spread_ms (and the thresholds beside them) move the same
    findings in both decoders, one pass and two."""
    for two_pass in (False, True):
        assert_same(c_tshark, lua_tshark, CAPTURES / name, two_pass, prefs)


def test_capture_list():
    """Every EG-Link capture of the generator is compared."""
    assert len(CAPTURE_NAMES) >= 33
    assert "crane_eglink.pcap" in CAPTURE_NAMES and "eglink_truncated.pcap" in CAPTURE_NAMES


# --- the twins, file by file -----------------------------------------------------

PLUGIN = ROOT / "plugins" / "vrshark"
LUA_MODULES = ROOT / "lua" / "vrshark"
# The files of the analysis in C and their Lua twins: eglink-X.c (or .h) and
# eglink_X.luam (eglink-analysis.h and eglink-compat.h are C only, the Lua
# modules' own: eglink_data.luam, the twin of packet-eglink.c's table).
C_ONLY = {"eglink-analysis.h", "eglink-compat.h"}
TWINS = {p: LUA_MODULES / (p.stem.replace("-", "_") + ".luam")
         for p in sorted(PLUGIN.glob("eglink-*.[ch]")) if p.name not in C_ONLY}
C_FUNCTION = re.compile(r"^(?:static )?[a-z_][\w ]*\**\n\**([a-z_]\w*)\(", re.M)
LUA_FUNCTION = re.compile(r"^(?:local )?function (?:M\.)?(\w+)\(", re.M)


def _c_names(path):
    """A C file's functions, without the eglink_ prefix the Lua names do without."""
    return {n[len("eglink_"):] if n.startswith("eglink_") else n for n in C_FUNCTION.findall(path.read_text())}


def test_twin_files():
    """Every file of the C analysis has its Lua twin of the same name and the
    other way round, and each header names its twin."""
    assert len(TWINS) >= 10
    lua = {p.name for p in LUA_MODULES.glob("eglink_*.luam")} - {"eglink_data.luam"}
    assert lua == {p.name for p in TWINS.values()}
    for c, luam in TWINS.items():
        assert "lua/vrshark/" + luam.name in c.read_text().split("*/", 1)[0], c.name
        assert "plugins/vrshark/" + c.name in luam.read_text().split("\nlocal ", 1)[0], luam.name


def test_twin_functions():
    """A function of the analysis with the same name in C and Lua is in the
    twin files: a reader finds its twin in the file of the same name."""
    c_files = {}
    for c in TWINS:
        for name in _c_names(c):
            c_files.setdefault(name, set()).add(c.name)
    shared = 0
    for c, luam in TWINS.items():
        for name in LUA_FUNCTION.findall(luam.read_text()):
            if name in c_files:
                assert c.name in c_files[name], (name, luam.name, c_files[name])
                shared += 1
    assert shared >= 75


# --- random sessions ----------------------------------------------------------

TYPES = ["VRPI", "VRPO", "VRCI", "VRCO", "VRAI", "VRAO"]
FROM_BU = {"VRPI", "VRCI", "VRAI"}


@st.composite
def vrpi_payload(draw):
    """Any VRPI: mostly valid values, sometimes any byte."""
    byte = st.integers(0, 255)
    if draw(st.integers(0, 3)) == 0:
        return draw(st.binary(min_size=46, max_size=46))
    return gen.vrpi(bu_state=draw(st.sampled_from([0, 1, 2, 3, 4, 0x10, 0x11, 0x11, 0x05, 0x12])),
                    vlaps=draw(st.integers(0, 4)), unarmed_rus=draw(byte), eg_link=draw(st.integers(0, 7)),
                    ec_link=draw(st.integers(0, 7)), c_link=draw(st.integers(0, 7)),
                    armed_ru=draw(st.sampled_from([0, gen.ARMED_RU, 0xCAFE])), ru_state=draw(st.integers(0, 5)),
                    battery=draw(st.integers(0, 101)), rssi=draw(st.integers(0, 101)),
                    cable=draw(st.integers(0, 2)), docked=draw(st.integers(0, 2)),
                    disabled=draw(st.integers(0, 4)),
                    joysticks=tuple(draw(st.lists(st.integers(-1001, 1001), min_size=4, max_size=4))),
                    switches=tuple(draw(st.lists(st.integers(-2, 2), min_size=8, max_size=8))),
                    encoder=draw(byte), encoder_switch=draw(st.integers(0, 2)),
                    spare=draw(st.sampled_from([bytes(6), b"\0\0\0\0\0\1"])))


@st.composite
def payload_of(draw, ptype):
    if ptype == "VRPI":
        return draw(vrpi_payload())
    if ptype == "VRPO":
        size = draw(st.sampled_from([0, 16, 64, 488, 488, 300]))
        return gen.vrpo(draw(st.integers(0, 3)), bytes((i * 7) & 0xFF for i in range(size)))
    if ptype in ("VRCI", "VRCO"):
        return gen.command(draw(st.integers(0, 5)), draw(st.binary(max_size=16)),
                           spare=draw(st.sampled_from([bytes(4), b"\0\0\0\1"])))
    return gen.ack(draw(st.integers(0, 5)))


@st.composite
def eglink_packet(draw, serials):
    """(t step, from BU, port offset, bytes, snap): a valid packet mostly; else
    corrupted: a wrong CRC variant or value, Size, revision, spare, origin,
    an unknown ID, bytes flipped, cut short, or cut by the capture."""
    ptype = draw(st.sampled_from(TYPES))
    from_bu = ptype in FROM_BU
    serials[from_bu] = (serials[from_bu] + draw(st.sampled_from([1, 1, 1, 1, 0, 2, 5]))) & 0xFFFF
    kw = dict(origin=(0x1001 if from_bu else 0), serial=serials[from_bu])
    fault = draw(st.sampled_from(["none"] * 8 + ["crc", "variant", "size", "header", "id", "flip", "short",
                                                 "snap", "extra"]))
    payload = draw(payload_of(ptype))
    if fault == "crc":
        kw["crc_value"] = draw(st.integers(0, 0xFFFFFFFF))
    elif fault == "variant":
        kw.update(crc=draw(st.sampled_from(["mpeg2", "bzip2", "iso_hdlc", "stm32"])),
                  crc_order=draw(st.sampled_from(["le", "be"])))
    elif fault == "size":
        kw["size"] = draw(st.integers(0, 600))
    elif fault == "header":
        kw.update(revision=draw(st.integers(0, 2)), spare=draw(st.sampled_from([0, 1, 0xFFFFFFFF])),
                  origin=draw(st.sampled_from([0, 0x1001, 0x2002])))
    elif fault == "id":
        ptype = "VR" + draw(st.sampled_from(["XI", "PX", "SI", "\x01\x02", "\xc3\xa9", "\xff\xfe", "P\n"]))
    elif fault == "extra":
        payload += draw(st.binary(min_size=1, max_size=8))
    pkt = _packet(ptype, payload, kw)
    snap = None
    if fault == "flip":
        pkt = bytearray(pkt)
        for _ in range(draw(st.integers(1, 4))):
            pkt[draw(st.integers(0, len(pkt) - 1))] ^= draw(st.integers(1, 255))
        pkt = bytes(pkt)
    elif fault == "short":
        pkt = pkt[:draw(st.integers(0, len(pkt) - 1))]
    elif fault == "snap":
        snap = draw(st.integers(1, len(pkt) + 8))
    step = draw(st.sampled_from([0.0, 0.001, 0.04, 0.125, 0.125, 0.6, 2.5, -0.5]))
    port_offset = draw(st.sampled_from([0] * 6 + [1000]))  # 1000: found by the heuristic (or not)
    return step, from_bu, port_offset, pkt, snap


def _packet(ptype, payload, kw):
    """gen.packet() with any 4 bytes as the ID."""
    body = gen.packet("VRPI", payload, **{k: v for k, v in kw.items() if k not in ("crc", "crc_order", "crc_value")})
    ident = ptype.encode("latin-1")
    body = ident + body[4:-4]
    value = kw.get("crc_value")
    if value is None:
        value = gen.CRC[kw.get("crc", "mpeg2")](body)
    return body + value.to_bytes(4, "little" if kw.get("crc_order", "le") == "le" else "big")


@st.composite
def session(draw):
    serials = {True: draw(st.integers(0, 0xFFFF)), False: draw(st.integers(0, 0xFFFF))}
    return draw(st.lists(eglink_packet(serials), min_size=1, max_size=40))


def write_session(path, packets):
    cap = Capture()
    t = 0.0
    for i, (step, from_bu, port_offset, pkt, snap) in enumerate(packets):
        t = max(0.0, t + step)
        port = gen.INPUT_PORT + port_offset + (0 if from_bu else 2)
        frame = udp_frame(gen.BU_IP if from_bu else gen.CTRL_IP, gen.MCAST, port, port, pkt,
                          src_mac=gen.BU_MAC if from_bu else gen.CTRL_MAC, ip_id=i + 1)
        if snap:
            cap.add(t, frame[:max(14, len(frame) - snap)], orig_len=len(frame))
        else:
            cap.add(t, frame)
    path.write_bytes(cap.to_bytes())
    path.chmod(0o644)
    return path


PREFS = [None, {"eglink.crc_variant": "stm32"}, {"eglink.crc_byte_order": "be"},
         {"eglink.heuristic": "FALSE"}, {"eglink.input_port": "5825,6825"},
         {"eglink.resend_tolerance_ms": "0", "eglink.burst_spread_ms": "0"}]


@settings(max_examples=int(os.environ.get("VRSHARK_PARITY_EXAMPLES", "12")), **SETTINGS)
@given(packets=session(), prefs=st.sampled_from(PREFS), two_pass=st.booleans())
def test_random_session_parity(c_tshark, lua_tshark, work_dir, packets, prefs, two_pass):
    """Random valid and corrupted packets of one BU and its controller, on the
    EG-Link ports or others, under the preferences a field engineer sets."""
    path = write_session(work_dir / ("session-%d.pcap" % next(_runs)), packets)
    assert_same(c_tshark, lua_tshark, path, two_pass, prefs)


def test_random_bytes(c_tshark, lua_tshark, work_dir):
    """Random bytes after "VR" on the EG-Link ports: decoded as far as they
    go, never a Lua error, as the C plugin decodes them."""
    rng = random.Random(43)
    packets = []
    for i in range(300):
        n = rng.choice([2, 3, 4, 10, 16, 19, 20, 21, 22, 40, 66, 510, 600])
        pkt = b"VR" + bytes(rng.randrange(256) for _ in range(n - 2))
        snap = rng.choice([None, None, None, rng.randrange(1, n + 9)])
        packets.append((0.01, i % 2 == 0, 0, pkt, snap))
    path = write_session(work_dir / "random-bytes.pcap", packets)
    lua_tshark.run(["-n", "-r", str(path), "-V", "-2"])  # (run() fails on a Lua Error)
    assert_same(c_tshark, lua_tshark, path, False)


def test_c_plugin_decodes_where_both_are_loaded(c_tshark, lua_tshark):
    """Where the C plugin is loaded, eglink.lua registers nothing and says
    nothing (no duplicate protocol, nothing on stderr); without it, the Lua
    EG-Link is the protocol eglink."""
    proc = c_tshark.run(["-G", "protocols"])
    assert "VisionRemote EG-Link\tEG-Link\teglink" in proc.stdout.splitlines() and proc.stderr == ""
    proc = c_tshark.run(["-n", "-r", str(CAPTURES / "eglink_armed.pcap"), "-c", "1"])
    assert " EG-Link " in proc.stdout and proc.stderr == ""
    plugins = c_tshark.run(["-G", "plugins"]).stdout
    assert "vrshark.so" in plugins and "eglink.lua" in plugins
    proc = lua_tshark.run(["-G", "protocols"])
    assert "VisionRemote EG-Link\tEGLINK\teglink" in proc.stdout.splitlines() and proc.stderr == ""
    assert "vrshark.so" not in lua_tshark.run(["-G", "plugins"]).stdout
