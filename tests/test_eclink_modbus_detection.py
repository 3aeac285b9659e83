"""EC-Link over Modbus/TCP detection: the heuristic (evidence only a BU
gives), the detection preference, the port preference, the poll gap, and no
false positives on ordinary Modbus traffic."""
import os
import re
import subprocess
from pathlib import Path

import pytest

from conftest import CAPTURES, Tshark
from modbus_testlib import FastTcpConnection, Traffic, bu_connection, modbus_client, read_input
from tools.capgen import eclink_modbus as mbgen

ALWAYS = {"eclink_modbus.detection": "always"}


def test_late_accept(tshark, capture_file):
    """Output writes (4, 8) before and between the input images (7, 11, 15):
    recognized in 15, the third input image of a PCI chain, after two
    consistent writes. One pass shows 15 on; the second pass shows the
    earlier frames of the connection too."""
    cap = capture_file("eclink_modbus_late_accept.pcap")
    names = ["eclink.image", "eclink.pco", "eclink.pci", "eclink_modbus.accepted_in"]
    one = tshark.frames(cap, names, display_filter="eclink_modbus")
    assert sorted(one) == list(range(15, 22))
    tshark.expect(cap, 15, {"eclink.image": "input", "eclink.pci": 3, "eclink_modbus.accepted_in": 15})
    tshark.expect(cap, 16, {"eclink.image": "output", "eclink.pco": 4, "eclink_modbus.accepted_in": 15})
    tshark.expect(cap, 4, {"eclink.image": None, "eclink_modbus.accepted_in": None})
    tshark.expect(cap, 7, {"eclink.image": None, "eclink_modbus.accepted_in": None})
    two = tshark.frames(cap, names, display_filter="eclink_modbus", two_pass=True)
    assert sorted(two) == list(range(4, 22))
    tshark.expect(cap, 4, {"eclink.image": "output", "eclink.pco": 1, "eclink_modbus.accepted_in": 15},
                  two_pass=True)
    tshark.expect(cap, 7, {"eclink.image": "input", "eclink.pci": 1, "eclink_modbus.accepted_in": 15},
                  two_pass=True)
    for frame in range(15, 22):
        assert two[frame] == one[frame]


def test_detection_always(tshark, capture_file):
    cap = capture_file("eclink_modbus_late_accept.pcap")
    got = tshark.frames(cap, ["eclink.image", "eclink.pco", "eclink_modbus.accepted_in"],
                        display_filter="eclink_modbus", prefs=ALWAYS)
    assert sorted(got) == list(range(4, 22))
    tshark.expect(cap, 4, {"eclink.image": "output", "eclink.pco": 1, "eclink_modbus.accepted_in": None},
                  prefs=ALWAYS)
    tshark.expect(cap, 5, {"eclink.image": None, "eclink.pco": None}, prefs=ALWAYS)


def test_detection_off(tshark, capture_file):
    cap = capture_file("eclink_modbus_basic.pcap")
    off = {"eclink_modbus.detection": "off"}
    assert tshark.frames(cap, ["eclink.image"], display_filter="eclink || eclink_modbus", prefs=off) == {}
    assert tshark.frames(cap, ["eclink.image"], display_filter="eclink || eclink_modbus", prefs=off,
                         two_pass=True) == {}
    # Modbus itself is still decoded
    assert len(tshark.frames(cap, ["modbus.func_code"], display_filter="modbus", prefs=off)) == 48


def test_plain_devices_not_decoded(tshark, capture_file):
    cap = capture_file("modbus_plain_devices.pcap")
    for two in (False, True):
        assert tshark.frames(cap, ["eclink.image"], display_filter="eclink || eclink_modbus", two_pass=two) == {}
    assert len(tshark.frames(cap, ["modbus.func_code"], display_filter="modbus")) == 2 * (6 * 5 + 6 * 3 + 4)


def _write(traffic, work_dir, name):
    return traffic.write(work_dir, name)


def test_eg_link_unused_is_recognized(tshark, work_dir):
    """An EC-Link-only BU (EG-Link status 0 Unused, EC-Link 1): recognized by
    its third input image (PCI 0, 1, 2 at the 125 ms cadence), read only."""
    traffic = Traffic()
    _, reads = bu_connection(traffic, dict(eg=0, ec=1, cl=1), polls=8, poll=0.125)
    cap = _write(traffic, work_dir, "eg_unused.pcap")
    frames = [r[0] for r in reads]
    assert frames == [5, 7, 9, 11, 13, 15, 17, 19]
    names = ["eclink.image", "eclink.pci", "eclink.eg_link_status", "eclink.ec_link_status",
             "eclink_modbus.accepted_in"]
    one = tshark.frames(cap, names, display_filter="eclink.image")
    assert sorted(one) == frames[2:]
    tshark.expect(cap, 9, {"eclink.image": "input", "eclink.pci": 2, "eclink.eg_link_status": 0,
                           "eclink.ec_link_status": 1, "eclink_modbus.accepted_in": 9})
    two = tshark.frames(cap, names, display_filter="eclink.image", two_pass=True)
    assert sorted(two) == frames
    tshark.expect(cap, 5, {"eclink.pci": 0, "eclink.eg_link_status": 0, "eclink_modbus.accepted_in": 9},
                  two_pass=True)


def test_eg_link_unused_with_output_write(tshark, work_dir):
    """The same BU with a controller that writes the output image (6, 10, ...):
    recognized on its third input image (13), the writes before it consistent."""
    traffic = Traffic()
    bu_connection(traffic, dict(eg=0, ec=1, cl=6, armed_ru=0, ru_state=0, battery=0, rssi=0, bu_state=0x10),
                  polls=4, poll=0.125, write=True)
    cap = _write(traffic, work_dir, "eg_unused_write.pcap")
    tshark.expect(cap, 13, {"eclink.image": "input", "eclink.pci": 2, "eclink_modbus.accepted_in": 13})
    tshark.expect(cap, 14, {"eclink.image": "output", "eclink.pco": 2, "eclink_modbus.accepted_in": 13})
    for frame in (5, 6, 9, 10):
        tshark.expect(cap, frame, {"eclink.image": None})
    tshark.expect(cap, 5, {"eclink.image": "input", "eclink.bu_state": 0x10, "eclink_modbus.accepted_in": 13},
                  two_pass=True)
    tshark.expect(cap, 6, {"eclink.image": "output", "eclink.pco": 0, "eclink_modbus.accepted_in": 13},
                  two_pass=True)


def test_one_valid_image_is_not_enough(tshark, work_dir):
    """Servers whose registers pass the checks of one image but show no BU behaviour."""
    traffic = Traffic()
    # 0/1 flags (the device of the issue): every register 0 or 1, read 40 times at 0..31
    mb, _ = traffic.client()
    for i in range(40):
        flags = bytes(b for k in range(32) for b in (((k * 7 + i) % 3 == 0) * 1, 0))
        read_input(mb, traffic.t + 0.05 * i, 4, mbgen.regs(flags))
    traffic.done(traffic.t + 2.1)
    # a valid image that never changes (PCI does not move)
    bu_connection(traffic, {}, polls=20, poll=0.125, phase=0.0)
    stream_static, _ = traffic.n - 1, None
    mb, _ = traffic.client()
    for i in range(20):
        read_input(mb, traffic.t + 0.125 * i, 4, mbgen.input_image(pci=7))
    traffic.done(traffic.t + 2.6)
    # PCI counting once per read at 20 ms: too fast for the BU's 125 ms
    mb, _ = traffic.client()
    for i in range(40):
        read_input(mb, traffic.t + 0.02 * i, 4, mbgen.input_image(pci=i))
    traffic.done(traffic.t + 0.9)
    # PCI moving in step but the BU state changing with every image
    mb, _ = traffic.client()
    states = [0x00, 0x01, 0x02, 0x03, 0x04, 0x10, 0x11]
    for i in range(20):
        read_input(mb, traffic.t + 0.125 * i, 4, mbgen.input_image(pci=i, bu_state=states[i % 7]))
    traffic.done(traffic.t + 2.6)
    cap = _write(traffic, work_dir, "not_enough.pcap")
    # (the real BU's images stop with its connection: the first frame after
    # their deadlines, of the next connection, says so, and is none of its own)
    stops = "eclink_modbus.input_missing || eclink_modbus.output_missing"
    got = tshark.frames(cap, ["tcp.stream"], display_filter="eclink_modbus && !(%s)" % stops, two_pass=True)
    streams = sorted({int(v["tcp.stream"]) for v in got.values()})
    assert streams == [1]  # only the real BU (stream 1) among them
    assert stream_static == 1


def test_bounded_tries_leave_room(tshark, work_dir):
    """A controller polling every 1 ms, read only: some 500 frames before PCI
    has moved twice; still recognized (the C front end tries 1024 frames)."""
    traffic = Traffic()
    _, reads = bu_connection(traffic, {}, polls=400, poll=0.001, phase=0.0)
    cap = _write(traffic, work_dir, "fast_poll.pcap")
    accepted = tshark.frames(cap, ["eclink_modbus.accepted_in"], display_filter="eclink_modbus.accepted_in")
    first = min(accepted)
    assert first > 256 * 2 - 20
    pci_at = {frame: pci for frame, _, pci in reads}
    assert pci_at[first] == 2 and pci_at[first - 2] == 1
    assert {f for f, _, _ in reads if f >= first} <= set(accepted)


def test_port_preference_one_setting(tshark, capture_file):
    """eclink_modbus.port alone: Wireshark's Modbus dissector classifies
    queries and responses (pairs them) and never says it cannot."""
    cap = capture_file("eclink_modbus_port5020.pcap")
    prefs = {"eclink_modbus.port": "5020"}
    tshark.expect(cap, 5, {"modbus.request_frame": 4, "eclink.pci": 1, "eclink_modbus.request_in": 4},
                  prefs=prefs, two_pass=True)
    tshark.expect(cap, 7, {"modbus.request_frame": 6, "eclink_modbus.request_in": 6}, prefs=prefs, two_pass=True)
    for env in ({}, {"VRSHARK_NO_C_PLUGIN": "1"}):
        for extra in (["-V"], []):
            out = subprocess.run([tshark.cmd, "-n", "-r", str(cap), "-o", "eclink_modbus.port:5020"] + extra,
                                 env=dict(tshark.env, **env), capture_output=True, text=True, timeout=600).stdout
            assert "classify" not in out.lower()
        assert out.count("Query: Trans:") == 8 and out.count("Response: Trans:") == 8
    # without the setting, port 5020 is none of ours
    assert tshark.frames(cap, ["eclink.image"], display_filter="eclink") == {}


@pytest.fixture(scope="module")
def lua_only_tshark(conf_dir):
    """tools/tshark without the C plugin (the Lua-only install's path)."""
    t = Tshark(conf_dir)
    t.env["VRSHARK_NO_C_PLUGIN"] = "1"
    return t


def test_port_not_set_says_which_setting(tshark, lua_only_tshark, capture_file):
    """Neither setting names port 5020: each request that reads the input
    image or writes the output image carries the candidate note naming the
    setting that decodes its server: while the requests are too few for the
    heuristic (two input image reads, frames 4-10) the server with its port,
    from the third read 250 ms after the first (frame 12) the ports already
    decoded with 5020, under which the heuristic judges it. The responses
    and the handshake stay plain TCP. One pass and two agree; with either
    setting the note is gone and the BU decoded."""
    cap = capture_file("eclink_modbus_port5020.pcap")
    note = ("Looks like a request to a BU's Modbus/TCP server (an image access) on TCP port 5020, which is not "
            "read as Modbus/TCP: not decoded%s; to decode it: %s")
    pin, port = "eclink_modbus.servers:192.168.2.41:5020", "eclink_modbus.port:502,5020"
    fields = ["tcp.dstport", "eclink_modbus.candidate_setting", "_ws.expert.message", "_ws.col.Protocol"]
    for t in (tshark, lua_only_tshark):
        for two_pass in (False, True):
            got = t.frames(cap, fields, two_pass=two_pass)
            requests = [n for n, row in got.items() if row["tcp.dstport"] == "5020" and n > 3]
            assert requests == [4, 6, 8, 10, 12, 14, 16, 18]
            for n, row in got.items():
                if n in requests:
                    setting = pin if n < 12 else port
                    short = ", too few requests yet for the heuristic" if n < 12 else ""
                    assert row == {"tcp.dstport": "5020", "eclink_modbus.candidate_setting": setting,
                                   "_ws.expert.message": note % (short, setting),
                                   "_ws.col.Protocol": "Modbus/TCP?"}, n
                else:
                    assert (row["eclink_modbus.candidate_setting"], row["_ws.col.Protocol"]) == ("", "TCP"), n
    for prefs in ({"eclink_modbus.port": "502,5020"}, {"eclink_modbus.servers": "192.168.2.41:5020"}):
        decoded = tshark.frames(cap, ["eclink_modbus.candidate", "eclink.image"], prefs=prefs, two_pass=True)
        assert [r["eclink_modbus.candidate"] for r in decoded.values()] == [""] * len(decoded)
        assert sum(1 for r in decoded.values() if r["eclink.image"]) == 8   # 4 input images read, 4 outputs written
    # the settings of the notes keep what the user has set and add to it
    got = tshark.frames(cap, ["eclink_modbus.candidate_setting"], display_filter="eclink_modbus.candidate",
                        prefs={"eclink_modbus.port": "502,600-610", "eclink_modbus.servers": "10.0.0.1"})
    assert [v["eclink_modbus.candidate_setting"] for v in got.values()] == [
        "eclink_modbus.servers:10.0.0.1,192.168.2.41:5020"] * 4 + ["eclink_modbus.port:502,600-610,5020"] * 4


@pytest.mark.parametrize("prefs", [{"eclink_modbus.port": "5020"}, {"mbtcp.tcp.port": "5020"},
                                   {"eclink_modbus.port": "502,5020"}, {"eclink_modbus.port": "5000-5030"}],
                         ids=["ours", "wiresharks", "list", "range"])
@pytest.mark.parametrize("lua_only", [False, True], ids=["C", "lua-only"])
def test_port_setting_adds_never_takes_away(tshark, lua_only_tshark, capture_file, prefs, lua_only):
    """eclink_modbus.port is a range (502 by default) and the port of
    Wireshark's Modbus/TCP dissector is decoded too: a port set here or
    there adds to 502, never takes it away. The BU on 502 (faults capture)
    and the one on 5020 decode in the same run as each alone, with the C
    front end and without."""
    t = lua_only_tshark if lua_only else tshark
    fields = ["eclink.image", "eclink.pci", "eclink_modbus.accepted_in", "_ws.expert.message"]
    on502 = capture_file("eclink_modbus_faults.pcap")
    alone = t.frames(on502, fields, two_pass=True)
    assert sum(1 for v in alone.values() if v["eclink.image"]) >= 15
    assert t.frames(on502, fields, two_pass=True, prefs=prefs) == alone
    on5020 = t.frames(capture_file("eclink_modbus_port5020.pcap"), fields, two_pass=True, prefs=prefs)
    assert sum(1 for v in on5020.values() if v["eclink.image"]) == 8




def _poll_gap_capture(work_dir):
    """A BU read every 125 ms; the controller stops reading for 1.090 s once."""
    traffic = Traffic()
    mb, _ = traffic.client()
    t0 = traffic.t + 0.01
    times = [t0 + 0.125 * i for i in range(6)]
    times += [times[-1] + 1.090 + 0.125 * i for i in range(4)]
    frames = []
    for t in times:
        pci = int((t - t0) / 0.125) & 0xFF
        req, _ = read_input(mb, t, 4, mbgen.input_image(pci=pci))
        mb.write_regs(t + 0.004, 0, mbgen.regs(mbgen.output_image(pco=pci)))
        frames.append(req)
    traffic.done(times[-1])
    return _write(traffic, work_dir, "poll_gap.pcap"), frames


def test_poll_gap(tshark, work_dir):
    cap, reads = _poll_gap_capture(work_dir)
    late = reads[6]
    exp = tshark.experts(cap)
    assert exp[late] == ["Input image not read for 1.090 s (PCI timeout 0.500 s)"]
    assert [f for f, msgs in exp.items() if any("not read" in m for m in msgs)] == [late]
    tshark.expect(cap, late, {"eclink_modbus.poll_gap": 1, "eclink_modbus.poll_gap_time": 1.09,
                              "eclink_modbus.poll_gap_from": reads[5],
                              "_ws.expert.severity": 0x00600000, "_ws.expert.group": 0x02000000})  # warning, sequence
    info = tshark.frames(cap, ["_ws.col.Info"], display_filter="frame.number == %d" % late)[late]["_ws.col.Info"]
    assert info.endswith("[poll gap 1.090 s]")
    # the same in two passes (but the notes of one pass on the frames before
    # the connection is recognized: decoded on the second); a longer timeout: no warning
    one = {f: [m for m in msgs if not m.startswith("Looks like a BU")] for f, msgs in exp.items()}
    assert tshark.experts(cap, two_pass=True) == {f: msgs for f, msgs in one.items() if msgs}
    assert tshark.frames(cap, ["frame.number"], display_filter="eclink_modbus.poll_gap",
                         prefs={"eclink_modbus.pci_timeout": "1200"}) == {}


def test_public_modbus_not_decoded(tshark, public_capture):
    cap = public_capture("modbus_example.pcap")
    assert tshark.field(cap, "frame.number", display_filter="eclink || eclink_modbus") == []
    assert tshark.field(cap, "frame.number", display_filter="eclink || eclink_modbus", two_pass=True) == []


def _plain_tshark_verbose(cap, conf_dir, tmp):
    """-V of the system tshark with none of our plugins."""
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8", WIRESHARK_CONFIG_DIR=str(conf_dir), HOME=str(tmp))
    env.pop("WIRESHARK_PLUGIN_DIR", None)
    proc = subprocess.run(["tshark", "-n", "-r", str(cap), "-V"], env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def _normalize(text):
    # the one difference a wrapping dissector cannot avoid: its name in the layer list
    return re.sub(r":eclink_modbus(?=[:\]])", "", text)


@pytest.mark.parametrize("which", ["public", "plain"])
def test_modbus_decoding_unchanged(tshark, public_capture, conf_dir, work_dir, which):
    cap = public_capture("modbus_example.pcap") if which == "public" else CAPTURES / "modbus_plain_devices.pcap"
    ours = tshark.verbose(cap)
    plain = _plain_tshark_verbose(cap, conf_dir, work_dir)
    assert "Modbus" in plain
    assert "eclink" not in _normalize(ours)
    assert _normalize(ours) == plain


def test_eclink_capture_keeps_modbus_tree(tshark, capture_file, conf_dir, work_dir):
    """On an EC-Link capture the Modbus trees are those of plain Wireshark; ours are added after them."""
    cap = capture_file("eclink_modbus_segments.pcap")
    ours = tshark.verbose(cap)
    plain = _plain_tshark_verbose(cap, conf_dir, work_dir)
    kept = []
    skip = False
    for line in _normalize(ours).splitlines():
        # (one pass: the note on a frame before the connection is recognized)
        if line.startswith("EC-Link over Modbus/TCP") or line.startswith("[Setting that decodes this server"):
            skip = True
            continue
        if skip and line.startswith(" "):
            continue
        skip = False
        kept.append(line)
    assert "\n".join(kept) + "\n" == plain


def test_no_lua_errors_anywhere(tshark):
    """Every committed capture, verbose, one and two passes: no Lua error (the fixture checks)."""
    caps = sorted(Path(CAPTURES).glob("eclink_modbus_*.pcap")) + sorted(Path(CAPTURES).glob("modbus_plain_*.pcap"))
    assert len(caps) >= 9
    for cap in caps:
        tshark.verbose(cap)
        tshark.verbose(cap, two_pass=True, prefs={"eclink_modbus.assembled": "TRUE"})
        tshark.verbose(cap, prefs={"eclink_modbus.detection": "always"})


def test_output_side_over_several_writes(tshark, work_dir):
    """A valid input chain is not enough while the controller's writes are
    not those of a BU's controller: PCO jumping about, or the periodic data
    size changing with every write (an IO device's 112 registers written
    with counting values). The same chain with consistent writes is
    recognized."""
    traffic = Traffic()
    streams = {}
    for name, pco_of, size_of in [("pco jumps", lambda i: (i * 100) & 0xFF, lambda i: 8),
                                  ("size changes", lambda i: i, lambda i: 10 + i),
                                  ("consistent", lambda i: i, lambda i: 8)]:
        mb, streams[name] = traffic.client()
        t0 = traffic.t + 0.01
        for i in range(12):
            t = t0 + 0.125 * i
            read_input(mb, t, 4, mbgen.input_image(pci=i))
            mb.write_regs(t + 0.004, 0, mbgen.regs(mbgen.output_image(pco=pco_of(i), size=size_of(i))))
        traffic.done(t0 + 1.6)
    cap = _write(traffic, work_dir, "output_side.pcap")
    for two in (False, True):
        got = tshark.frames(cap, ["tcp.stream"], display_filter="eclink_modbus", two_pass=two)
        assert sorted({int(v["tcp.stream"]) for v in got.values()}) == [streams["consistent"]]


def test_dropped_when_images_stop_being_valid(tshark, work_dir):
    """A connection recognized on a BU's run whose server then answers with
    images no BU makes (spare bytes not 0, PCI frozen): the eighth invalid
    image in a row drops it with one note; later frames are Modbus/TCP only,
    instead of alarms on every frame."""
    traffic = Traffic()
    mb, _ = traffic.client()
    t0 = traffic.t + 0.01
    frames = []
    for i in range(20):
        t = t0 + 0.125 * i
        img = mbgen.input_image(pci=i) if i < 6 else mbgen.input_image(pci=1, spare=b"\1\1\1\1", eg=9)
        frames.append(read_input(mb, t, 4, img)[1])
    traffic.done(t0 + 2.6)
    cap = _write(traffic, work_dir, "dropped.pcap")
    dropped = frames[6 + 7]
    for two in (False, True):
        exp = tshark.experts(cap, two_pass=two)
        notes = {f: [x for x in m if "no longer" in x] for f, m in exp.items() if any("no longer" in x for x in m)}
        assert notes == {dropped: ["8 input images in a row not valid: connection (recognized in frame %d) no "
                                   "longer taken for a BU's; left to Modbus/TCP until it is recognized again"
                                   % frames[2]]}
        got = tshark.frames(cap, ["eclink.image"], display_filter="eclink_modbus", two_pass=two)
        shown = sorted(got)
        assert shown[-1] == dropped and not [f for f in frames if f > dropped and f in got]
        # the images before the drop still tell what is wrong with them
        assert "Spare bytes 60..63 are not 0" in exp[frames[6]]
        tshark.expect(cap, dropped + 2, {"eclink.image": None, "modbus.func_code": 4}, two_pass=two)


def test_reopened_connection_on_the_same_ports(tshark, work_dir):
    """A BU's controller closes its connection and opens a new one from the
    same client port (Wireshark gives it a new tcp.stream): the connection
    is known by its addresses and ports, on the C front end's side as on
    the decoder's, so the new one is decoded from its first input image,
    and an ordinary device's connection beside it stays Modbus's."""
    traffic = Traffic()
    fields = {"bu_state": 4}
    mb = modbus_client(traffic.cap, "10.0.0.1", 40000, "10.7.0.1", 502, traffic.t)
    t = traffic.t + 0.01
    for i in range(12):
        read_input(mb, t + i * 0.04, 4, mbgen.input_image(pci=(i // 3) & 0xFF, **fields))
    traffic.done(t + 12 * 0.04)
    # (new initial sequence numbers: TCP takes the SYN for a new connection)
    again = mbgen.ModbusClient.__new__(mbgen.ModbusClient)
    again.conn = FastTcpConnection(traffic.cap, "10.0.0.1", 40000, "10.7.0.1", 502, client_isn=900000,
                                   server_isn=700000)
    again.conn.handshake(traffic.t)
    again.tid, again.unit = 0, 1
    t = traffic.t + 0.01
    firsts = [read_input(again, t + i * 0.04, 4, mbgen.input_image(pci=(20 + i // 3) & 0xFF, **fields))[1]
              for i in range(6)]
    plain = modbus_client(traffic.cap, "10.0.0.1", 40001, "10.7.0.2", 502, t + 0.5)
    plain_resp = [plain.read_regs(t + 0.6 + i * 0.04, 4, 0, bytes([i % 7 + 1] * 64))[1] for i in range(6)]
    cap = traffic.write(work_dir, "reopened.pcap")
    for two_pass in (False, True):
        got = tshark.frames(cap, ["tcp.stream", "eclink.image", "eclink.pci"], two_pass=two_pass)
        assert got[firsts[0]]["tcp.stream"] != got[3]["tcp.stream"]
        for n, frame in enumerate(firsts):
            assert got[frame]["eclink.image"] == "input", (two_pass, frame)
            assert got[frame]["eclink.pci"] == str(20 + n // 3), (two_pass, frame)
        assert all(got[f]["eclink.image"] == "" for f in plain_resp), two_pass
