"""EC-Link over Modbus/TCP: a BU's image streams that stop, and a PLC
connection to a BU that ends, against a real Modbus/TCP stack (pymodbus
servers and a pymodbus PLC on 127.0.0.x, captured on lo with dumpcap).

Five pymodbus BUs (the BU of test_eclink_modbus_realstack, PCI moving every
125 ms) and its three ordinary servers. The PLC reads every BU's input
image and writes its 224-byte output image every 50 ms, and polls the
ordinary servers. At CUT s each BU meets its fault, and the ordinary
servers are polled on for another 2.6 s (past both limits):
- STOPPED: the BU server shuts down (its FIN); the PLC stops polling it;
- CLOSED: the PLC closes its connection (the PLC's FIN);
- RESET: the PLC resets its connection (SO_LINGER 0: RST);
- SILENT: the PLC stops polling it, the connection stays open;
- READ_ONLY: the PLC reads on but stops writing the output image.

TS-0007 8.3 (PCI timeout, 500 ms) and 8.4 (PCO, 2000 ms) are rules on the
images: every BU that is no longer read gets eclink_modbus.input_missing
on the first frame after the last read + 500 ms, every BU no longer written
eclink_modbus.output_missing on the first frame after the last write +
2000 ms; a FIN or RST on a BU's connection gets
eclink_modbus.connection_closed / connection_reset on the next frame
dissected. The expected frames come from the capture's own TCP fields (the
frames with a payload on the port: what the plugins dissect), the same in
one pass and with -2, with the C plugin and the Lua plugins alone.
"""
import os
import shutil
import signal
import socket
import struct
import tempfile
import time
from pathlib import Path

import pytest

import test_eclink_modbus_realstack as rs
from conftest import ROOT, expert_infos

STOPPED, CLOSED, RESET, SILENT, READ_ONLY = "127.0.0.1", "127.0.0.6", "127.0.0.7", "127.0.0.8", "127.0.0.9"
BUS = [STOPPED, CLOSED, RESET, SILENT, READ_ONLY]
CUT = 1.5
RUN_S = CUT + 2.6

# the BU servers of test_eclink_modbus_realstack, one a fault; SIGUSR1 shuts STOPPED down
MAIN = r'''
import signal


async def stops():
    bus = {ip: ModbusTcpServer(context("bu"), address=(ip, PORT)) for ip in %r}
    others = [ModbusTcpServer(context(kind), address=(ip, PORT)) for ip, kind in plant[1:4]]
    loop = asyncio.get_running_loop()
    loop.add_signal_handler(signal.SIGUSR1, lambda: asyncio.ensure_future(bus[%r].shutdown()))
    await asyncio.gather(*(s.serve_forever() for s in list(bus.values()) + others), return_exceptions=True)

plant = [("127.0.0.1", "bu"), ("127.0.0.2", "flags"), ("127.0.0.3", "counters"), ("127.0.0.4", "random")]
asyncio.run(stops())
''' % (BUS, STOPPED)

PREFS = rs.PREFS


def _plc(log):
    bus = {ip: rs._client(ip) for ip in BUS}
    others = [rs._client(ip) for ip in rs.ORDINARY]
    live, writing = list(BUS), set(BUS)
    t0 = time.monotonic()
    cut, pco = False, 1
    while time.monotonic() - t0 < RUN_S:
        if not cut and time.monotonic() - t0 >= CUT:
            cut = True
            log["servers"].send_signal(signal.SIGUSR1)
            bus[CLOSED].close()
            bus[RESET].socket.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            bus[RESET].close()
            live = [READ_ONLY]
            writing = set()
        for ip in live:
            assert not bus[ip].read_input_registers(0, count=32, device_id=1).isError()
            if ip in writing:
                assert not bus[ip].write_registers(0, rs._output_registers(pco, 5), device_id=1).isError()
        pco = (pco + 1) & 0xFF
        for client in others:
            assert not client.read_input_registers(0, count=32, device_id=1).isError()
        time.sleep(0.05)
    log["cut"] = True
    for client in [bus[STOPPED], bus[SILENT], bus[READ_ONLY]] + others:
        client.close()


@pytest.fixture(scope="module")
def stops_capture():
    folder = Path(tempfile.mkdtemp(prefix="vrshark-stops-"))
    folder.chmod(0o777)
    try:
        cap, log = rs._capture(folder, "stops", _plc, rs.SERVERS.replace("asyncio.run(main())", MAIN))
        assert log.get("cut")
        yield cap
    finally:
        shutil.rmtree(folder, ignore_errors=True)


TCP = ["frame.time_epoch", "ip.src", "ip.dst", "tcp.srcport", "tcp.dstport", "tcp.len", "tcp.flags.fin",
       "tcp.flags.reset", "modbus.func_code", "modbus.reference_num"]
ERROR, WARNING, SEQUENCE = "8388608", "6291456", "33554432"
FINDINGS = ["eclink_modbus.input_missing", "eclink_modbus.output_missing", "eclink_modbus.connection_closed",
            "eclink_modbus.connection_reset"]
FILTER = " || ".join(FINDINGS)

# With the C plugin, frames of servers not taken for a BU reach Lua through
# the C front ends' clock hook (lua/vrshark/deadlines.luam, on_change); where
# that hook is not built, the first frame after a deadline that reaches Lua
# is one of a BU's connections.
LUA_ONLY = os.environ.get("VRSHARK_NO_C_PLUGIN") == "1"
CLOCK_HOOK = any("on_change" in p.read_text() for p in (ROOT / "lua" / "vrshark").glob("*.luam")
                 if p.name != "deadlines.luam")


def _seen(v):
    """A frame the plugins dissect (a TCP payload on the port; without the
    clock hook and with the C plugin: on a BU's connection)."""
    if not v["tcp.len"] or int(v["tcp.len"]) == 0:
        return False
    return LUA_ONLY or CLOCK_HOOK or v["ip.src"] in BUS and v["ip.dst"] in BUS


def _expected(tshark, cap):
    """From the TCP fields alone: {frame: sorted [(expert field, severity,
    message)]}, {frame: sorted [(missing_since, missing_time)]}, {frame:
    [closed_in]}, {frame: [Info tags]}."""
    got = tshark.frames(cap, TCP, prefs=PREFS)
    frames = sorted(got)
    t = {n: float(got[n]["frame.time_epoch"]) for n in frames}
    seen = [n for n in frames if _seen(got[n])]

    def first_seen_after(when):
        return next(n for n in seen if t[n] > when)

    def requests(ip, fc):
        return [n for n in frames if got[n]["ip.dst"] == ip and got[n]["tcp.dstport"] == str(rs.PORT)
                and got[n]["modbus.func_code"] == str(fc) and got[n]["modbus.reference_num"] == "0"]
    experts, links, ends, tags = {}, {}, {}, {}
    for ip in BUS:
        for fc, kind, verb, limit, rule in ((4, "input", "read", 0.5, "PCI timeout 0.500 s, TS-0007 8.3"),
                                            (16, "output", "written", 2.0, "PCO timeout 2.000 s, TS-0007 8.4")):
            if fc == 4 and ip == READ_ONLY:
                continue
            last = requests(ip, fc)[-1]
            n = first_seen_after(t[last] + limit)
            gap = t[n] - t[last]
            experts.setdefault(n, []).append((
                "eclink_modbus.%s_missing" % kind, ERROR,
                "BU %s:%d unit 1: %s image not %s for %.3f s (%s): last %s in frame %d"
                % (ip, rs.PORT, kind, verb, gap, rule, verb, last)))
            links.setdefault(n, []).append((last, gap))
            tags.setdefault(n, []).append("[no %s %.3f s]" % (kind, gap))
    for ip in (STOPPED, CLOSED, RESET):
        # (after the PLC's first read: a refused connect before the servers listen is no BU's)
        cport = got[requests(ip, 4)[-1]]["tcp.srcport"]
        ends_of = {(ip, str(rs.PORT), cport), ("127.0.0.1", cport, str(rs.PORT))}
        end = next(n for n in frames if n > requests(ip, 4)[0]
                   and (got[n]["ip.src"], got[n]["tcp.srcport"], got[n]["tcp.dstport"]) in ends_of
                   and (got[n]["tcp.flags.fin"] == "1" or got[n]["tcp.flags.reset"] == "1"))
        reset = got[end]["tcp.flags.reset"] == "1"
        from_bu = got[end]["ip.src"] == ip
        client_port = got[end]["tcp.dstport"] if from_bu else got[end]["tcp.srcport"]
        n = next(m for m in seen if m > end)
        experts.setdefault(n, []).append((
            "eclink_modbus.connection_" + ("reset" if reset else "closed"), WARNING,
            "TCP connection of the PLC (127.0.0.1:%s) to BU %s:%d %s in frame %d (from the %s): input image "
            "(unit 1) last read in frame %d, output image (unit 1) last written in frame %d"
            % (client_port, ip, rs.PORT, "reset by RST" if reset else "closed by FIN", end,
               "BU" if from_bu else "PLC", requests(ip, 4)[-1], requests(ip, 16)[-1])))
        ends.setdefault(n, []).append(str(end))
        tags.setdefault(n, []).append("[connection to BU %s]" % ("reset" if reset else "closed"))
    return ({n: sorted(v) for n, v in experts.items()}, {n: sorted(v) for n, v in links.items()}, ends, tags,
            got)


@pytest.fixture(scope="module")
def expected(tshark, stops_capture):
    return _expected(tshark, stops_capture)


@pytest.mark.parametrize("two_pass", [False, True])
def test_streams_that_stop_and_connections_that_end(tshark, stops_capture, expected, two_pass):
    cap = stops_capture
    experts, links, ends, tags, tcp = expected
    # every BU's fault, each on its own frame or sharing one
    assert sum(len(v) for v in experts.values()) == 4 * 2 + 1 + 3
    got = {}
    for frame, name, sev, group, msg, _ in expert_infos(tshark.json(cap, prefs=PREFS, two_pass=two_pass,
                                                                    display_filter=FILTER)):
        if name in FINDINGS:
            assert group == SEQUENCE
            got.setdefault(frame, []).append((name, sev, msg))
    assert {n: sorted(v) for n, v in got.items()} == experts
    fields = tshark.frames(cap, ["eclink_modbus.missing_since", "eclink_modbus.missing_time",
                                 "eclink_modbus.closed_in", "_ws.col.Info"],
                           prefs=PREFS, two_pass=two_pass, display_filter=FILTER)
    assert sorted(fields) == sorted(experts)
    for n, v in fields.items():
        since = [int(x) for x in v["eclink_modbus.missing_since"].split(",") if x]
        times = [float(x) for x in v["eclink_modbus.missing_time"].split(",") if x]
        pairs = sorted(zip(since, times))
        assert [p[0] for p in pairs] == [w[0] for w in links.get(n, [])], n
        assert all(abs(p[1] - w[1]) < 2e-6 for p, w in zip(pairs, links.get(n, []))), n
        assert [x for x in v["eclink_modbus.closed_in"].split(",") if x] == ends.get(n, []), n
        for tag in tags[n]:
            assert tag in v["_ws.col.Info"], (n, tag)
    # the ordinary servers' polls go on past the last finding, with nothing of ours
    assert max(tcp) > max(experts)


@pytest.mark.parametrize("two_pass", [False, True])
def test_the_stops_capture(tshark, capture_file, two_pass):
    """eclink_modbus_stops.pcap (tools/capgen/eclink_modbus.py:stops): each
    end followed first by a frame of a BU's connection, the ordinary server
    polled throughout (tests/findings_faults.py has the schedule)."""
    cap = capture_file("eclink_modbus_stops.pcap")
    names = ["eclink_modbus.missing_since", "eclink_modbus.missing_time", "eclink_modbus.closed_in",
             "_ws.col.Info"]
    got = tshark.frames(cap, names, two_pass=two_pass, display_filter=FILTER)
    assert sorted(got) == [94, 127, 211, 275]
    exp = tshark.experts(cap, two_pass=two_pass)
    assert exp[94] == ["BU 192.168.2.41:502 unit 1: input image not read for 0.510 s (PCI timeout 0.500 s, "
                       "TS-0007 8.3): last read in frame 60"]
    tshark.expect(cap, 94, {"eclink_modbus.missing_since": 60, "eclink_modbus.missing_time": "0.510000000",
                            "eclink_modbus.closed_in": None}, two_pass=two_pass)
    # (the tag after the frame's own image summary: the clock ticks once the frame is shown)
    assert got[94]["_ws.col.Info"].endswith("Write Multiple Registers [EC-Link output PCO=9 "
                                            "CCO=0 CAO=0 size=0 block=0] [no input 0.510 s]")
    assert exp[127] == ["TCP connection of the PLC (192.168.2.10:50100) to BU 192.168.2.41:502 closed by FIN in "
                        "frame 124 (from the PLC): input image (unit 1) last read in frame 60, output image (unit 1) "
                        "last written in frame 110"]
    tshark.expect(cap, 127, {"eclink_modbus.closed_in": 124, "eclink_modbus.missing_since": None}, two_pass=two_pass)
    assert got[127]["_ws.col.Info"].endswith("Read Input Registers [connection to BU closed]")
    assert exp[211] == ["BU 192.168.2.41:502 unit 1: output image not written for 2.020 s (PCO timeout 2.000 s, "
                        "TS-0007 8.4): last written in frame 110"]
    tshark.expect(cap, 211, {"eclink_modbus.missing_since": 110, "eclink_modbus.missing_time": "2.020000000"},
                  two_pass=two_pass)
    # BU 2's old connection's images go on over the new one (recognised before
    # their deadlines): no stream of BU 2 stops
    assert exp[275] == ["TCP connection of the PLC (192.168.2.10:50101) to BU 192.168.2.42:502 reset by RST in "
                        "frame 271 (from the BU): input image (unit 1) last read in frame 265, output image (unit 1) "
                        "last written in frame 267"]
    tshark.expect(cap, 275, {"eclink_modbus.closed_in": 271}, two_pass=two_pass)
    assert "[connection to BU reset]" in got[275]["_ws.col.Info"]


@pytest.mark.parametrize("two_pass", [False, True])
def test_who_listens_for_the_ends(lua_probe, capture_file, two_pass):
    """The FIN and RST of a BU's connection come from a listener of the tcp tap, which runs on
    every TCP frame: with the C plugin its own, in C (plugins/vrshark/vrshark-tcpends.c), so no
    Lua listener is made; without it one Lua listener, made when the first connection is taken
    for a BU's. The findings are the same in both (test_the_stops_capture)."""
    script = """
local f = io.open("%(out)s", "w")
local new = Listener.new
Listener.new = function(tap, ...)
    f:write("listener " .. tostring(tap) .. "\\n")
    f:flush()
    return new(tap, ...)
end
"""
    lines = lua_probe(script, capture_file("eclink_modbus_stops.pcap"),
                      ["-Y", "eclink_modbus.connection_closed || eclink_modbus.connection_reset"]
                      + (["-2"] if two_pass else []))
    assert lines == (["listener tcp"] if os.environ.get("VRSHARK_NO_C_PLUGIN") else [])
