"""The C front ends (plugins/vrshark/vrshark-frontends.c): which frames reach Lua.

A probe script (-X lua_script) takes the place of the Lua decoders in the
front ends' hooks and writes down every call: hook, frame number, pass.
It re-registers itself after every frame (as a postdissector), since the
decoders register their hooks again when a file starts; so every capture
here starts with one frame that is neither PROFINET nor Modbus.
"""
import os
import subprocess

import pytest
from scapy.utils import rdpcap

from tools.capgen import eclink_modbus as mbgen
from tools.capgen import profinet as pngen
from tools.capgen.frames import pn_rt_frame, udp_frame
from tools.capgen.pcap import Capture

from conftest import CAPTURES
from seam_testlib import CONTRACT

# These tests are about the C plugin: a Lua-only run (VRSHARK_NO_C_PLUGIN=1) skips them.
needs_c = pytest.mark.skipif(bool(os.environ.get("VRSHARK_NO_C_PLUGIN")), reason="runs without the C plugin")

PN_TRIES = CONTRACT["PN_CANDIDATE_TRIES"]
MB_TRIES = CONTRACT["MB_CANDIDATE_TRIES"]

PROBE = r"""
local out = assert(io.open(os.getenv("VRSHARK_PROBE_OUT"), "w"))
local accept_from = tonumber(os.getenv("VRSHARK_PROBE_ACCEPT") or "0")
local probe = Proto("vrshark_probe", "front end probe")
local install
function probe.dissector(tvb, pinfo, tree)
    if pinfo.match_string == nil then install(pinfo.number) return 0 end  -- the postdissector call
    out:write(string.format("%s %d %s\n", pinfo.match_string, pinfo.number, tostring(pinfo.visited)))
    out:flush()
    if accept_from > 0 and pinfo.number >= accept_from then return tvb:len() end
    return 0
end
-- (through the contract, as the decoders: vrshark/frontends.luam puts a
-- hook into its table, a flag or a listed server into the C plugin's state)
local fe = require("vrshark.frontends")
local seam = require("vrshark.seam")
-- (the server listed only after frame `from` up to frame `to`, when given)
local from, to = (os.getenv("VRSHARK_PROBE_SERVER_FRAMES") or ""):match("^(%d+)-(%d+)$")
function install(number)
    fe.hook(fe.pn_hook, seam.PN_HOOK_CANDIDATE, probe, true)
    fe.hook(fe.pn_hook, seam.PN_HOOK_CONNECT, probe, true)
    -- a decoder that holds an AR learned from a request wants the responses
    if os.getenv("VRSHARK_PROBE_RESPONSE") == "1" then fe.hook(fe.pn_hook, seam.FLAG_PN_RESPONSE, probe, true) end
    fe.hook(fe.mb_hook, seam.MB_HOOK_HEURISTIC, probe, true)
    -- a listed server, as eclink_modbus.servers lists it
    local server = os.getenv("VRSHARK_PROBE_SERVER") or ""
    if server ~= "" then
        local on = not from or (number >= tonumber(from) and number < tonumber(to))
        fe.hook(fe.mb_hook, seam.MB_HOOK_SERVER, probe, on)
        fe.hook(fe.mb_hook, seam.MB_SERVER_PREFIX .. server, probe, on)
    end
end
register_postdissector(probe)
"""


def _filler():
    return udp_frame("10.0.0.1", "10.0.0.2", 40000, 40001, b"filler")


def _write(cap, work_dir, name):
    path = work_dir / name
    path.write_bytes(cap.to_bytes())
    path.chmod(0o644)
    return path


def _probe(tshark, work_dir, capture, two_pass=False, accept_from=0, extra=(), server="", response=False,
           server_frames=""):
    """[(hook, frame, visited)] of every call into the probe."""
    script = work_dir / "probe.lua"
    script.write_text(PROBE)
    script.chmod(0o644)
    out = work_dir / ("probe-%d-%d.txt" % (two_pass, accept_from))
    out.touch()
    out.chmod(0o666)
    env = dict(tshark.env, VRSHARK_PROBE_OUT=str(out), VRSHARK_PROBE_ACCEPT=str(accept_from),
               VRSHARK_PROBE_SERVER=server, VRSHARK_PROBE_RESPONSE="1" if response else "0",
               VRSHARK_PROBE_SERVER_FRAMES=server_frames)
    args = [tshark.cmd, "-n", "-r", str(capture), "-X", "lua_script:%s" % script] + list(extra)
    if two_pass:
        args.append("-2")
    proc = subprocess.run(args, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "Lua Error" not in proc.stdout + proc.stderr
    rows = []
    for line in out.read_text().splitlines():
        hook, frame, visited = line.split()
        rows.append((hook, int(frame), visited == "true"))
    return rows


def _foreign_cyclic(work_dir):
    """A filler, then 100 cycles of a foreign device (FrameIDs 0x8100 in, 0x8101
    out) and 10 frames with FrameID 0x0100 (outside the candidate range)."""
    cap = Capture()
    cap.add(0.0, _filler())
    frames = {0x8100: [], 0x8101: [], 0x0100: []}
    for i in range(100):
        for fid, src, dst in ((0x8100, "00:0e:8c:00:00:07", "00:1b:1b:00:00:09"),
                              (0x8101, "00:1b:1b:00:00:09", "00:0e:8c:00:00:07")):
            frames[fid].append(cap.add(0.001 * (i + 1), pn_rt_frame(src, dst, fid, bytes([0x80]) * 40, cycle=i)))
    for i in range(10):
        frames[0x0100].append(cap.add(0.2 + 0.001 * i, pn_rt_frame("00:0e:8c:00:00:07", "00:1b:1b:00:00:09",
                                                                   0x0100, bytes(40), cycle=i)))
    return _write(cap, work_dir, "foreign_cyclic.pcap"), frames


@needs_c
@pytest.mark.parametrize("two_pass", [False, True])
def test_unknown_frame_ids_are_tried_a_bounded_number_of_times(tshark, work_dir, two_pass):
    cap, frames = _foreign_cyclic(work_dir)
    calls = _probe(tshark, work_dir, cap, two_pass=two_pass)
    assert all(hook == "candidate" and not visited for hook, _, visited in calls)
    called = [frame for _, frame, _ in calls]
    assert called == sorted(frames[0x8100][:PN_TRIES] + frames[0x8101][:PN_TRIES])


@needs_c
def test_an_accepted_candidate_is_not_counted(tshark, work_dir):
    """A candidate the decoder takes costs no try: after 60 refusals of FrameID
    0x8100, accepting from frame 122 on keeps every later frame coming."""
    cap, frames = _foreign_cyclic(work_dir)
    calls = _probe(tshark, work_dir, cap, accept_from=122)
    called = {frame for _, frame, _ in calls}
    assert set(frames[0x8100]) <= called
    assert set(frames[0x8101]) <= called
    assert not called & set(frames[0x0100])


@needs_c
@pytest.mark.parametrize("response", [True, False])
@pytest.mark.parametrize("two_pass", [False, True])
def test_only_connects_reach_the_connect_hook(tshark, work_dir, capture_file, response, two_pass):
    """Of the PNIO-CM datagrams, the Connect request goes to Lua, and on the
    first pass its response while the decoder says (flag FLAG_PN_RESPONSE)
    that it holds an AR learned from a request: a capture of foreign devices hands it
    none. On the second pass the response goes to it whatever the flag says
    (an AR held on the first pass may have been dropped since)."""
    src = capture_file("mcmb2_duplex_cm_port.pcap")
    cap = Capture()
    cap.add(0.0, _filler())
    for i, frame in enumerate([bytes(p) for p in rdpcap(str(src))]):
        cap.add(0.001 * (i + 1), frame)
    path = _write(cap, work_dir, "cm_port.pcap")
    calls = _probe(tshark, work_dir, path, two_pass=two_pass, response=response)
    connects = tshark.field(path, "frame.number", display_filter="dcerpc.opnum == 0")
    assert connects == ["2", "3"]
    assert tshark.field(path, "dcerpc.pkt_type", display_filter="dcerpc.opnum == 0") == ["0", "2"]
    # (the probe returns 0: without an AR held, the request it refused is
    # not handed over again, on any pass)
    first = [(2, False), (3, False)] if response else [(2, False)]
    second = [(2, True), (3, True)] if response else [(3, True)]
    want = first + (second if two_pass else [])
    assert [(frame, visited) for hook, frame, visited in calls if hook == "connect"] == want


@needs_c
@pytest.mark.parametrize("response", [True, False])
def test_foreign_connect_requests_are_handed_over_once(tshark, work_dir, capture_file, response):
    """A Connect request the decoder returned 0 for (no system of ours) is
    not handed over again with the same expected submodules while it holds
    no AR (flag FLAG_PN_RESPONSE off); a request with other submodules is. With
    an AR held, every request and response goes to it."""
    def connects(name):
        frames = [bytes(p) for p in rdpcap(str(capture_file(name)))]
        return [frames[int(n) - 1] for n in tshark.field(capture_file(name), "frame.number",
                                                          display_filter="dcerpc.opnum == 0")]
    a_req, a_resp = connects("mcmb2_duplex_cm_port.pcap")[:2]
    b_req = connects("mcmb2_polled_connect.pcap")[0]
    cap = Capture()
    cap.add(0.0, _filler())
    for i, frame in enumerate((a_req, a_resp, a_req, b_req, a_req, b_req)):
        cap.add(0.001 * (i + 1), frame)
    path = _write(cap, work_dir, "connect_repeats.pcap")
    assert tshark.field(path, "dcerpc.pkt_type", display_filter="dcerpc.opnum == 0") == ["0", "2", "0", "0", "0", "0"]
    calls = _probe(tshark, work_dir, path, response=response)
    want = [2, 3, 4, 5, 6, 7] if response else [2, 5]
    assert [frame for hook, frame, _ in calls if hook == "connect"] == want


def _modbus_plain(work_dir, transactions, image_shaped=True):
    """A client polling a server that is no BU. image_shaped: it reads input
    registers 0-31, as a controller reads a BU's input image (zeros here, which
    no BU sends); otherwise holding registers 0-9."""
    cap = Capture()
    cap.add(0.0, _filler())
    mb = mbgen.ModbusClient(cap, client_port=50300, server_ip="192.168.2.60", client_ip="192.168.2.11",
                            t=0.01)
    adus = []
    for i in range(transactions):
        if image_shaped:
            adus += mb.read_regs(0.02 + 0.01 * i, 4, 0, bytes(64))
        else:
            adus += mb.read_regs(0.02 + 0.01 * i, 3, 0, bytes(20))
    return _write(cap, work_dir, "modbus_plain.pcap"), adus


@needs_c
@pytest.mark.parametrize("two_pass", [False, True])
def test_modbus_connections_are_tried_a_bounded_number_of_frames(tshark, work_dir, two_pass):
    cap, adus = _modbus_plain(work_dir, 600)
    calls = _probe(tshark, work_dir, cap, two_pass=two_pass)
    # (later passes: what is looked at, e.g. "heuristic.quiet")
    assert all(hook.split(".")[0] == "heuristic" for hook, _, _ in calls)
    assert [frame for _, frame, visited in calls if not visited] == adus[:MB_TRIES]
    # a second pass: the frames looked at once, again (for the candidate notes), no other
    assert [frame for _, frame, visited in calls if visited] == (adus[:MB_TRIES] if two_pass else [])


@needs_c
def test_modbus_without_image_shaped_requests_never_reaches_lua(tshark, work_dir):
    """A client that never reads a whole input image nor writes an output
    image gives no evidence the heuristic could accept: none of its frames
    is handed to Lua (the cost of ordinary Modbus/TCP stays Wireshark's)."""
    cap, adus = _modbus_plain(work_dir, 50, image_shaped=False)
    assert len(adus) == 100
    assert _probe(tshark, work_dir, cap) == []


@needs_c
@pytest.mark.parametrize("server,reached", [("192.168.2.60", True), ("192.168.2.60:502", True),
                                            ("192.168.2.60:5020", False), ("192.168.2.61", False)])
def test_a_listed_modbus_server_gets_every_frame(tshark, work_dir, server, reached):
    """A server in eclink_modbus.servers (listed as "server ADDR" or "server
    ADDR:PORT"): every frame from the first, on both passes, even one that
    gives no evidence; another address or port: none."""
    cap, adus = _modbus_plain(work_dir, 20, image_shaped=False)
    calls = _probe(tshark, work_dir, cap, two_pass=True, server=server)
    if not reached:
        assert calls == []
        return
    assert all(hook.split(".")[0] == "server" for hook, _, _ in calls)
    assert [frame for _, frame, visited in calls if not visited] == adus
    assert [frame for _, frame, visited in calls if visited] == adus


@needs_c
def test_a_server_listed_for_a_while_gets_those_frames(tshark, work_dir):
    """The list of servers and hook "server" are the Lua side's word from the
    moment it says it (vrshark-flags.c; the front end reads the Modbus hooks
    again then), not once a file: listed after frame 12 and no longer after
    frame 30, the server gets frames 13 to 30 of the first pass."""
    cap, adus = _modbus_plain(work_dir, 20, image_shaped=False)
    calls = _probe(tshark, work_dir, cap, server="192.168.2.60:502", server_frames="12-30")
    assert [frame for _, frame, _ in calls] == [n for n in adus if 12 < n <= 30]
    assert all(hook.split(".")[0] == "server" for hook, _, _ in calls)


@needs_c
def test_an_accepted_modbus_connection_gets_every_frame(tshark, work_dir):
    """Accepted in frame 20: every later frame of the connection, on both passes."""
    cap, adus = _modbus_plain(work_dir, 20)
    calls = _probe(tshark, work_dir, cap, two_pass=True, accept_from=20)
    first = [frame for _, frame, visited in calls if not visited]
    second = [frame for _, frame, visited in calls if visited]
    assert first == adus
    assert second == adus


@needs_c
def test_foreign_modbus_keeps_wiresharks_layers(tshark, work_dir):
    cap, adus = _modbus_plain(work_dir, 3)
    protos = tshark.field(cap, "frame.protocols", display_filter="frame.number == %d" % adus[0])
    assert protos == ["eth:ethertype:ip:tcp:mbtcp:modbus"]


def test_lua_only_run_leaves_the_c_plugin_out(tshark, capture_file):
    """VRSHARK_NO_C_PLUGIN=1: no vrshark.so; the Lua plugins wrap PN-RT and mbtcp themselves, and
    EG-Link is the Lua one."""
    env = dict(tshark.env, VRSHARK_NO_C_PLUGIN="1")
    out = subprocess.run([tshark.cmd, "-G", "protocols"], env=env, capture_output=True, text=True,
                         timeout=600).stdout
    names = {line.split("\t")[2] for line in out.splitlines() if line.count("\t") >= 2}
    assert "vrshark_pnio" in names and "mcmb2" in names and "eclink_modbus" in names
    assert "vrshark_mbtcp" not in names
    assert "eglink" in names  # the Lua EG-Link (lua/eglink.lua), only without the C plugin
    rows = subprocess.run([tshark.cmd, "-n", "-r", str(capture_file("mcmb2_duplex_connect.pcap")), "-T", "fields",
                           "-e", "frame.protocols", "-e", "mcmb2.direction", "-c", "4"], env=env,
                          capture_output=True, text=True, timeout=600).stdout.splitlines()
    # (mcmb2's frames shown through its own dissector: its findings are
    # listed under MCMB2, lua/vrshark/pnio_systems.luam through())
    assert rows[2:] == ["eth:ethertype:vrshark_pnio:pn_rt:pn_io:mcmb2\tuplink",
                        "eth:ethertype:vrshark_pnio:pn_rt:pn_io:mcmb2\tdownlink"]
    assert os.environ.get("VRSHARK_NO_C_PLUGIN") or "vrshark_mbtcp" in subprocess.run(
        [tshark.cmd, "-G", "protocols"], env=tshark.env, capture_output=True, text=True, timeout=600).stdout


@pytest.mark.parametrize("capture", ["mcmb2_polled_connect.pcap", "eclink_modbus_faults.pcap"])
def test_expert_statistics_see_the_lua_findings(tshark, capture):
    """`tshark -q -z expert` builds no tree and no columns: the front ends must
    still let the Lua decoders add their expert info, since the expert tap
    listens. Every finding the decoders give in a normal run is counted."""
    path = str(CAPTURES / capture)
    out = tshark.run(["-n", "-q", "-r", path, "-z", "expert"]).stdout
    messages = {m for msgs in tshark.experts(CAPTURES / capture).values() for m in msgs}
    ours = {m for m in messages if not m.startswith(("Connection establish", "Connect request",
                                                        "Connect response"))}
    assert ours
    missing = [m for m in ours if m not in out]
    assert not missing, missing


def test_no_lua_field_costs_every_frame():
    """No plugin makes a Lua Field (Field.new): Wireshark feeds every Lua
    Field through a tap whose filter starts with "frame", so the frame tree of
    every packet of every protocol is built from then on (measured: a foreign
    PROFINET frame in tshark -Y cost 25 % more). Values the C plugin knows go
    to Lua in pinfo (eglink.data: pinfo.match_uint)."""
    from pathlib import Path
    lua = Path(__file__).resolve().parent.parent / "lua"
    users = [str(p) for p in sorted(lua.rglob("*.lu*")) if "Field.new" in p.read_text()]
    assert users == []
