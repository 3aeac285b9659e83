"""vrshark-report on streams that never come back before the capture ends,
and the health rows (tools/report/health.py), on traffic the project did
not make:

- scapy PROFINET (tests/pnio_testlib.py): an MC-MB2-PN duplex base and an
  EC-Link BU with their Connects, one direction removed after a point with
  `tshark -Y` as a field engineer cuts a capture;
- a pymodbus BU and PLC on 127.0.0.1 captured on lo (the plant of
  test_eclink_modbus_realstack.py): the PLC stops polling the BU while it
  polls the three ordinary servers on, or closes or resets its connection,
  or the BU's server stops;
- real UDP sockets: an EG-Link BU that stops sending VRPI while its
  controller goes on, with a command it sends that is never acknowledged.

The expected lines are computed from the captures themselves (frame
numbers and times as tshark reads them), never from the report's output.
A stream cut by the capture's own end within its limit is no finding.
"""
import json
import os
import shutil
import statistics
import subprocess
import sys
import time

import pytest

from conftest import ROOT, _world_dir

REPORT = ROOT / "tools" / "vrshark-report"


def run_report(capture, *args):
    """(exit status, JSON report) of tools/vrshark-report --json ARGS CAPTURE."""
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8")
    proc = subprocess.run([str(REPORT), "--json", "--no-progress"] + list(args) + [str(capture)],
                          env=env, cwd=str(ROOT), capture_output=True, text=True, timeout=300)
    assert proc.returncode in (0, 1), proc.stderr
    return proc.returncode, json.loads(proc.stdout)["captures"][0]


def run_text(capture, *args):
    env = dict(os.environ, TZ="UTC", LC_ALL="C.UTF-8")
    proc = subprocess.run([str(REPORT), "--no-progress"] + list(args) + [str(capture)],
                          env=env, cwd=str(ROOT), capture_output=True, text=True, timeout=300)
    return proc.stdout.splitlines()


def frames(tshark, capture, names, prefs=None):
    """[(frame number, seconds from the first frame, {name: value})] as tshark reads them."""
    got = tshark.fields(capture, ["frame.number", "frame.time_epoch"] + names, prefs=prefs)
    out, first = [], None
    for cols in got:
        epoch = float(cols[1])
        first = epoch if first is None else first
        out.append((int(cols[0]), epoch - first, dict(zip(names, cols[2:]))))
    return out


def stopped(rep):
    return [(e["frame"], e["severity"], e["text"]) for e in rep["timeline"] if e["kind"] == "stopped"]


def stop_line(label, last, end, limit_ms):
    frame, t, _ = last
    return "%s: last frame %d at %.3f s; the capture goes on %.3f s without it (limit %d ms)" % (
        label, frame, t, end - t, limit_ms)


def cut(tshark, folder, capture, name, keep):
    """The capture without the frames the display filter `keep` rejects (tshark -Y ... -w)."""
    out = folder / name
    tshark.run(["-r", str(capture), "-Y", keep, "-w", str(out)], cache=False)
    out.chmod(0o644)
    return out


# --- scapy PROFINET -----------------------------------------------------------------------

BASE_MAC, BU_MAC = "02:00:00:00:03:00", "02:00:00:00:03:01"
CYCLE = 0.050


@pytest.fixture(scope="module")
def pnio(tshark):
    """Whole captures of an MC-MB2-PN duplex base (uplink 0x8001, downlink 0x8002)
    and an EC-Link BU (input 0x8030, output 0x8031), 50 ms cycle, 3.2 s each;
    in the base's capture the uplink takes 0.3 s once (after its frame at
    1.0 s), and its watchdog stands still from 1.5 s to 2.7 s."""
    from pnio_testlib import CaptureFile, Device, eclink_submodules, mcmb2_submodules
    from test_pnio_midsession import eclink_image_in, eclink_image_out
    folder = _world_dir("vrshark-stops-", 0o777)   # (tshark, as nobody, writes the cuts)
    base = Device(mcmb2_submodules("duplex", 1, 2, 2, 0, 1), BASE_MAC, 0x8001, 0x8002)
    cap = CaptureFile()
    for pkt in base.connect():
        cap.add(pkt)
    t, watchdog = 0.0, 0
    for i in range(64):
        wait = 0.3 if i == 21 else CYCLE
        t += wait
        if not 1.5 <= t < 2.7:
            watchdog = (watchdog + 1) & 0xFF
        cap.add(base.cyclic("in", {1: bytes([0x11, watchdog]), 2: b"\x01\x02"}), wait - 0.001 if i else wait)
        cap.add(base.cyclic("out", {3: bytes([0, i & 0xFF]), 4: b"\x00\x00"}), 0.001)
    mcmb2 = cap.write(folder / "mcmb2.pcap")
    bu = Device(eclink_submodules(4, 224), BU_MAC, 0x8030, 0x8031)
    cap = CaptureFile()
    for pkt in bu.connect():
        cap.add(pkt)
    for i in range(64):
        cap.add(bu.cyclic("in", {1: eclink_image_in(i)}), CYCLE - 0.001)
        cap.add(bu.cyclic("out", {2: eclink_image_out(i)}), 0.001)
    eclink = cap.write(folder / "eclink.pcap")
    yield folder, mcmb2, eclink
    shutil.rmtree(folder, ignore_errors=True)


def direction(tshark, capture, src):
    """The frames of the capture, and of them those sent by src (a MAC address)."""
    got = frames(tshark, capture, ["eth.src", "pn_rt.frame_id"])
    return got, [f for f in got if f[2]["eth.src"] == src and f[2]["pn_rt.frame_id"]]


def one_stream_gone(tshark, folder, capture, name, display_filter, mac):
    """The capture cut by display_filter, its frames and those sent by mac,
    and the report with --fail-on error (which must exit 1)."""
    cut_capture = cut(tshark, folder, capture, name, display_filter)
    got, sent = direction(tshark, cut_capture, mac)
    status, rep = run_report(cut_capture, "--fail-on", "error")
    assert status == 1
    return cut_capture, got, sent, rep


def test_uplink_that_never_comes_back(tshark, pnio):
    """The base's uplink removed after 0.8 s, the downlink running on to 3.2 s:
    one error of the base at the uplink's last frame, none for the downlink,
    and --fail-on error exits 1."""
    folder, mcmb2, _ = pnio
    _, got, uplink, rep = one_stream_gone(tshark, folder, mcmb2, "no_uplink.pcap",
                                          "!(frame.time_relative > 0.8 && eth.src == %s)" % BASE_MAC, BASE_MAC)
    assert stopped(rep) == [(uplink[-1][0], "error", stop_line("uplink 0x8001", uplink[-1], got[-1][1], 1000))]
    assert [d["kind"] for d in rep["devices"]] == ["mcmb2"]
    row = {r["stream"]: r for r in rep["devices"][0]["streams"]}
    assert row["uplink 0x8001"]["longest_silence"] == {"s": round(got[-1][1] - uplink[-1][1], 6), "frame": None}
    assert row["uplink 0x8001"]["stalls"] == 1
    assert row["downlink 0x8002"]["stalls"] == 0


def test_downlink_that_never_comes_back(tshark, pnio):
    """The controller's downlink removed after 0.8 s: 2.4 s without it, past its 2 s."""
    folder, mcmb2, _ = pnio
    capture = cut(tshark, folder, mcmb2, "no_downlink.pcap",
                  "!(frame.time_relative > 0.8 && eth.dst == %s && pn_rt)" % BASE_MAC)
    got, _ = direction(tshark, capture, BASE_MAC)
    downlink = [f for f in got if f[2]["eth.src"] != BASE_MAC and f[2]["pn_rt.frame_id"]]
    status, rep = run_report(capture, "--fail-on", "error")
    assert status == 1
    assert stopped(rep) == [(downlink[-1][0], "error",
                             stop_line("downlink 0x8002", downlink[-1], got[-1][1], 2000))]


def test_stream_cut_by_the_capture_end_within_its_limit(tshark, pnio):
    """The downlink removed after 1.6 s: the capture ends 1.6 s later, within
    the downlink's 2 s: what the capture does not hold is unknown, no finding.
    The whole capture (both directions to its end) has none either."""
    folder, mcmb2, _ = pnio
    capture = cut(tshark, folder, mcmb2, "downlink_short.pcap",
                  "!(frame.time_relative > 1.6 && eth.dst == %s && pn_rt)" % BASE_MAC)
    assert stopped(run_report(capture)[1]) == []
    assert stopped(run_report(mcmb2)[1]) == []


def test_eclink_input_that_never_comes_back(tshark, pnio):
    """The BU's input frames removed after 0.8 s, its output running on: past PCI's 500 ms."""
    folder, _, eclink = pnio
    capture, got, inputs, rep = one_stream_gone(tshark, folder, eclink, "no_input.pcap",
                                                "!(frame.time_relative > 0.8 && eth.src == %s)" % BU_MAC, BU_MAC)
    assert stopped(rep) == [(inputs[-1][0], "error", stop_line("input 0x8030", inputs[-1], got[-1][1], 500))]
    text = run_text(capture)
    assert "%10.3f %7d  %-8s  [1]  %s" % (inputs[-1][1], inputs[-1][0], "error",
                                         stop_line("input 0x8030", inputs[-1], got[-1][1], 500)) in text


def test_health_rows_of_a_base(tshark, pnio):
    """The whole base capture: the rows' frames, cycle, the 0.3 s silence
    with the frame that ended it, the watchdog stall, the findings."""
    _, mcmb2, _ = pnio
    got, uplink = direction(tshark, mcmb2, BASE_MAC)
    ends_silence = uplink[21]
    assert round(ends_silence[1] - uplink[20][1], 3) == 0.3
    _, rep = run_report(mcmb2)
    rows = {r["stream"]: r for r in rep["devices"][0]["streams"]}
    up, down = rows["uplink 0x8001"], rows["downlink 0x8002"]
    assert (up["frames"], up["first_frame"], up["last_frame"]) == (64, uplink[0][0], uplink[-1][0])
    # (the intervals as the capture holds them, to the microsecond: scapy
    # truncates some 50 ms to 49.999)
    gaps = [round(b[1] - a[1], 6) * 1000 for a, b in zip(uplink, uplink[1:])]
    assert up["cycle_ms"] == {"min": round(min(gaps), 3), "median": round(statistics.median(gaps), 3),
                              "max": 300.0}
    assert 49.99 <= min(gaps) and statistics.median(gaps) == 50.0
    assert up["longest_silence"] == {"s": 0.3, "frame": ends_silence[0]}
    # the watchdog stood still 1.2 s: stalled (error) and slow (warning)
    assert (up["stalls"], up["commands_failed"], up["findings"]) == (
        1, 0, {"error": 1, "warning": 1, "note": 0})
    assert [e["field"] for e in rep["timeline"] if e["severity"] != "note"] == [
        "mcmb2.uplink_watchdog.slow", "mcmb2.uplink_watchdog.stalled"]
    assert (down["frames"], down["stalls"], down["findings"]) == (64, 0, {"error": 0, "warning": 0, "note": 0})
    assert down["limit_ms"] == 2000 and up["limit_ms"] == 1000
    text = run_text(mcmb2)
    i = text.index("health (per stream; cycle: the intervals between its frames):")
    assert text[i + 1].split() == ["device", "stream", "frames", "cycle", "ms", "min", "/", "median", "/", "max",
                                   "longest", "silence", "stalls", "failed", "findings", "E/W/N"]
    assert text[i + 2].split() == ["[1]", "uplink", "0x8001", "64", "%.1f" % min(gaps), "/", "50.0", "/", "300.0",
                                   "0.300", "s", "to", "frame", str(ends_silence[0]), "1", "0", "1/1/0"]


def test_health_rows_in_junit(tshark, pnio, work_dir):
    _, mcmb2, _ = pnio
    import xml.etree.ElementTree as ET
    out = work_dir / "r.xml"
    run_text(mcmb2, "--junit", str(out))
    props = {p.get("name"): p.get("value") for p in ET.parse(out).iter("property")}
    _, uplink = direction(tshark, mcmb2, BASE_MAC)
    gaps = [round(b[1] - a[1], 6) * 1000 for a, b in zip(uplink, uplink[1:])]
    assert props["health uplink 0x8001"] == (
        "frames 64; cycle %.1f / 50.0 / 300.0 ms; longest silence 0.300 s to frame %d; stalls 1; "
        "commands failed 0; findings 1 error, 1 warning, 0 note" % (min(gaps), uplink[21][0]))


# --- a pymodbus plant ----------------------------------------------------------------------

PLANT_S = 3.0      # the PLC polls the ordinary servers this long
BU_S = 0.8         # and the BU this long


def _plant_plc(how):
    """The plant's PLC: reads the BU's input image and writes its output image
    every 50 ms for BU_S, then (how) goes silent on the BU's connection,
    closes it (FIN) or resets it (RST), and polls the ordinary servers on."""
    import socket
    import struct
    import test_eclink_modbus_realstack as rs

    def plc(log):
        bu = rs._client(rs.BU)
        others = [rs._client(ip) for ip in rs.ORDINARY]
        start = time.monotonic()
        pco = 1
        while time.monotonic() < start + PLANT_S:
            if bu is not None and time.monotonic() < start + BU_S:
                rr = bu.read_input_registers(0, count=32, device_id=1)
                assert not rr.isError(), rr
                log["read"].append(rr.registers)
                assert not bu.write_registers(0, rs._output_registers(pco, rr.registers[0] >> 8),
                                              device_id=1).isError()
                pco = (pco + 1) & 0xFF
            elif bu is not None and how != "silent":
                if how == "reset":
                    bu.socket.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                bu.close()
                bu = None
            for client in others:
                assert not client.read_input_registers(0, count=32, device_id=1).isError()
            time.sleep(0.05)
        for client in others + ([bu] if bu is not None else []):
            client.close()
    return plc


def _servers(rs, folder, which):
    """The plant's pymodbus servers in a process of their own: "bu" the BU
    alone, "others" all but the BU."""
    script = folder / ("servers_%s.py" % which)
    script.write_text(rs.SERVERS.replace(
        '(plant[:1] if MODE == "commands" else plant)',
        '(plant[:1] if MODE == "bu" else plant[1:] if MODE == "others" else plant)'))
    return subprocess.Popen([sys.executable, str(script), str(rs.PORT), which], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)


def _bu_server_stops(folder):
    """The BU's server process ends after BU_S: the BU's side closes the
    connection, as a BU whose Modbus/TCP server stops does; the PLC polls
    the ordinary servers on."""
    import test_eclink_modbus_realstack as rs
    cap = folder / "plant-bu-stops.pcapng"
    others, bu_server = _servers(rs, folder, "others"), _servers(rs, folder, "bu")
    try:
        dumpcap = rs._start_capture(cap)
        try:
            bu = rs._client(rs.BU)
            clients = [rs._client(ip) for ip in rs.ORDINARY]
            start, pco = time.monotonic(), 1
            while time.monotonic() < start + PLANT_S:
                if bu is not None and time.monotonic() < start + BU_S:
                    rr = bu.read_input_registers(0, count=32, device_id=1)
                    assert not rr.isError(), rr
                    assert not bu.write_registers(0, rs._output_registers(pco, rr.registers[0] >> 8),
                                                  device_id=1).isError()
                    pco = (pco + 1) & 0xFF
                elif bu is not None:
                    bu_server.terminate()
                    bu_server.wait(timeout=10)
                    time.sleep(0.05)
                    bu.close()
                    bu = None
                for client in clients:
                    assert not client.read_input_registers(0, count=32, device_id=1).isError()
                time.sleep(0.05)
            for client in clients:
                client.close()
            time.sleep(0.2)
        finally:
            rs._stop(dumpcap)
    finally:
        for proc in (others, bu_server):
            proc.terminate()
            proc.wait(timeout=10)
    cap.chmod(0o644)
    return cap


@pytest.fixture(scope="module", params=["silent", "close", "reset", "server_stopped"])
def plant(request):
    import test_eclink_modbus_realstack as rs
    if request.param == "server_stopped":
        folder = _world_dir("vrshark-plant-", 0o777)
        try:
            yield request.param, _bu_server_stops(folder), rs.PORT
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        return
    for got in rs.captured("plant", _plant_plc(request.param)):
        yield request.param, got[0], rs.PORT


def test_plc_leaves_the_bu(tshark, plant):
    """Polled 0.8 s, then left while the ordinary servers are polled on to
    3 s: the input image read and the output image written stop (past
    500 ms and 2000 ms), and a closed or reset connection is named with its
    frame; --fail-on error exits 1."""
    how, capture, port = plant
    prefs = {"eclink_modbus.port": str(port)}
    got = frames(tshark, capture, ["eclink.image", "ip.src", "tcp.srcport", "tcp.dstport", "tcp.flags.fin",
                                   "tcp.flags.reset"], prefs=prefs)
    bu = [f for f in got if "127.0.0.1" in (f[2]["ip.src"],) and f[2]["eclink.image"]]
    reads = [f for f in bu if "input" in f[2]["eclink.image"]]
    writes = [f for f in bu if "output" in f[2]["eclink.image"]]
    end = got[-1][1]
    assert end - writes[-1][1] > 2.0
    status, rep = run_report(capture, "--fail-on", "error", "-o", "eclink_modbus.port:%d" % port)
    assert status == 1
    [dev] = [d for d in rep["devices"] if d["kind"] == "eclink_modbus"]
    assert dev["name"] == "EC-Link BU, Modbus/TCP server 127.0.0.1:%d" % port
    want = [(reads[-1][0], "error", stop_line("input image read (unit 1)", reads[-1], end, 500)),
            (writes[-1][0], "error", stop_line("output image written (unit 1)", writes[-1], end, 2000))]
    if how != "silent":
        # the first FIN or RST of the BU's connection after its last image, by
        # the PLC (to the BU's port) or, its server stopped, by the BU
        flag = "tcp.flags.reset" if how == "reset" else "tcp.flags.fin"
        by_bu = how == "server_stopped"
        close = [f for f in got if f[0] > writes[-1][0] and f[2][flag] == "1"
                 and f[2]["tcp.srcport" if by_bu else "tcp.dstport"] == str(port)][0]
        client = "127.0.0.1:%s" % close[2]["tcp.dstport" if by_bu else "tcp.srcport"]
        words = "reset (RST)" if how == "reset" else "closed (FIN)"
        want.append((close[0], "error", "connection %s to 127.0.0.1:%d %s by the %s in frame %d at %.3f s; "
                     "the capture goes on %.3f s without it" % (client, port, words, "BU" if by_bu else "PLC",
                                                                close[0], close[1], end - close[1])))
    assert sorted(e for e in stopped(rep) if e[2].startswith(("input", "output", "connection"))) == sorted(want)
    rows = {r["stream"]: r for r in dev["streams"]}
    assert rows["input image read (unit 1)"]["frames"] == len(reads)
    assert rows["output image written (unit 1)"]["frames"] == len(writes)
    assert rows["input image read (unit 1)"]["stalls"] == 1
    assert rows["input image read (unit 1)"]["commands_failed"] == 0


# --- EG-Link over real UDP sockets ----------------------------------------------------------

@pytest.fixture(scope="module")
def vrpi_stops():
    """A BU (origin 0x1001) sends VRPI every 100 ms for 0.8 s and a command
    (VRCI 5, sent again 100 ms later) its controller never acknowledges;
    the controller sends VRPO every 100 ms for 3 s."""
    from test_report_model import capture_on_lo, mcast_socket
    from eglink_testlib import gen
    folder = _world_dir("vrshark-vrpi-stops-", 0o755)
    path = folder / "vrpi_stops.pcap"
    bu, ctrl = mcast_socket(), mcast_socket()
    group = "239.255.42.20"

    def send():
        serial = 0
        for i in range(30):
            if i < 8:
                bu.sendto(gen.packet("VRPI", gen.armed(), origin=0x1001, serial=serial), (group, 5825))
                serial += 1
                if i in (2, 3):
                    bu.sendto(gen.packet("VRCI", gen.command(5, b"\x01\x00HORN"), origin=0x1001, serial=serial),
                              (group, 5825))
                    serial += 1
            ctrl.sendto(gen.packet("VRPO", gen.vrpo(0, gen.machine_data(i)), serial=i), (group, 5827))
            time.sleep(0.1)

    capture_on_lo(path, (bu, ctrl), send)
    yield path
    shutil.rmtree(folder, ignore_errors=True)


def test_vrpi_that_never_comes_back(tshark, vrpi_stops):
    """The BU's VRPI stops at 0.8 s while its controller's VRPO runs on to 3 s:
    one error at the last VRPI; the BU's row counts the stop once (the
    dissector's VRPI gap, open to the end, is the same stop) and the command
    it sent that failed."""
    got = frames(tshark, vrpi_stops, ["eglink.type"])
    vrpi = [f for f in got if f[2]["eglink.type"] == "VRPI"]
    vrpo = [f for f in got if f[2]["eglink.type"] == "VRPO"]
    status, rep = run_report(vrpi_stops, "--fail-on", "error")
    assert status == 1
    assert stopped(rep) == [(vrpi[-1][0], "error", stop_line("BU VRPI", vrpi[-1], got[-1][1], 500))]
    [dev] = rep["devices"]
    rows = {r["stream"]: r for r in dev["streams"]}
    # the dissector's open VRPI gap counts the stop; the end-of-capture entry is the same stop
    assert rows["BU VRPI"]["stalls"] == 1
    assert rows["BU VRPI"]["frames"] == len(vrpi)
    assert rows["BU VRPI"]["commands_failed"] == 1, [e["text"] for e in rep["timeline"]]
    assert rows["controller VRPO"]["frames"] == len(vrpo)
    assert (rows["controller VRPO"]["stalls"], rows["controller VRPO"]["commands_failed"]) == (0, 0)
    command = [f for f in got if f[2]["eglink.type"] == "VRCI"][0][0]
    assert [e["text"] for e in rep["timeline"] if e["field"] == "eglink.analysis.vrci_unacked"] == [
        "VRCI of frame %d not acknowledged in time: the command failed" % command]


def test_clock_findings_filed_under_the_bu_they_name(capture_file):
    """eclink_modbus_stops.pcap: the shared clock puts a BU's missing image
    and its ended connection on the first frame after the deadline, here
    frames of the other BU's connection (127, 211); the report files each
    under the BU its message names (192.168.2.41, device 1), not under the
    frame's (device 2), and the other BU's rows count none of them."""
    _, rep = run_report(capture_file("eclink_modbus_stops.pcap"))
    got = {(e["frame"], e["field"]): e["device"] for e in rep["timeline"] if e["kind"] == "finding"}
    assert got == {(94, "eclink_modbus.input_missing"): 1, (127, "eclink_modbus.connection_closed"): 1,
                   (211, "eclink_modbus.output_missing"): 1, (275, "eclink_modbus.connection_reset"): 2}
    other = [d for d in rep["devices"] if d["id"] == 2][0]
    assert all(s["stalls"] == 0 for s in other["streams"]), other["streams"]


def test_profinet_stops_on_frames_of_no_device(capture_file):
    """mcmb2_duplex_stops.pcap: the downlink's stop and its data hold time
    are said on frames of a foreign PROFINET device (330, 350): the report
    files them under the base whose stream ended in the frame they link
    (mcmb2.missing_since 329), with no note of no device beside them."""
    _, rep = run_report(capture_file("mcmb2_duplex_stops.pcap"))
    got = {(e["frame"], e["field"]): e["device"] for e in rep["timeline"] if e["kind"] == "finding"}
    assert got[(309, "mcmb2.uplink_missing")] == 1
    assert got[(350, "mcmb2.downlink_missing")] == 1
    assert [e for e in rep["timeline"] if e["device"] is None] == []
    down = [s for s in rep["devices"][0]["streams"] if s["stream"].startswith("downlink")][0]
    assert down["stalls"] >= 1, down
