"""EC-Link over Modbus/TCP against a real Modbus/TCP stack (pymodbus, pinned
in requirements.txt), captured on the loopback interface with dumpcap.

A pymodbus server on 127.0.0.1 plays a BU: its input registers 0..31 hold an
input image whose PCI moves every 125 ms (EG-Link Unused, EC-Link only). A
pymodbus client plays the PLC: it reads the input image, echoes CCI in CAO
and writes the output image (holding registers 0..111), logging what it read
and wrote. Three ordinary servers on 127.0.0.2..4 (0/1 flags, counters,
random registers) are polled at registers 0..31 beside it, and an ordinary
IO device on 127.0.0.5 (0/1 digital inputs changing every few cycles) is
polled exactly as a PLC polls a BU: the whole input image (input registers
0..31), 112 holding registers written from 0 (values counting up) and a
read/write (function 23), every 100-125 ms. All servers use
one free port above 1024 (not 502), named in the one setting
eclink_modbus.port.

Skipped (with the reason) only where capturing on lo is impossible.
"""
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest



def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


PORT = _free_port()
BU = "127.0.0.1"
ORDINARY = {"127.0.0.2": "flags", "127.0.0.3": "counters", "127.0.0.4": "random"}
BU_LIKE = "127.0.0.5"       # an ordinary IO device polled like a BU
RUN_S = 2.0

SERVERS = r'''
import asyncio, random, sys, time
from pymodbus.datastore import ModbusDeviceContext, ModbusSequentialDataBlock, ModbusServerContext
from pymodbus.server import ModbusTcpServer

PORT = int(sys.argv[1])
# "commands": the BU alone, its RU sending CCI 6 at 0.5 s and CCI 7 at 4 s
MODE = sys.argv[2] if len(sys.argv) > 2 else "plant"
T0 = time.monotonic()
rnd = random.Random(1)


def bu_image():
    """The BU's input image now: PCI every 125 ms, joystick 1 following it."""
    t = time.monotonic() - T0
    pci = int(t / 0.125) & 0xFF
    joy = (pci * 37) % 1000
    cci = 5 if MODE != "commands" or t < 0.5 else 6 if t < 4.0 else 7
    img = bytes([pci, cci, 0, 9]) + b"FROM-RU-COMMAND!"
    img += bytes([0x11, 1, 0, 0, 1, 1]) + (0x4242).to_bytes(2, "big")     # Armed; EG-Link Unused, EC, C-Link 1
    img += bytes([3, 77, 88, 0, 0, 0]) + joy.to_bytes(2, "big", signed=True) + bytes(6)
    img += bytes(16) + bytes([42, 0]) + bytes(4)
    return img


class Registers(ModbusSequentialDataBlock):
    """Input registers computed on every read (pymodbus passes address + 1)."""

    def __init__(self, kind):
        super().__init__(0, [0] * 2200)
        self.kind, self.reads = kind, 0

    def getValues(self, address, count=1):
        self.reads += 1
        if self.kind == "bu":
            img = bu_image()
            regs = [img[2 * k] | img[2 * k + 1] << 8 for k in range(32)]   # image byte 2n in the low byte
        elif self.kind == "flags":
            regs = [rnd.randrange(2) for _ in range(32)]
        elif self.kind == "io":
            # 0/1 digital inputs: three steadily on, three changing every few
            # reads, the rest off (every value check of an input image passes)
            regs = [0] * 32
            regs[10] = regs[12] = regs[13] = 1
            for k in (0, 5, 16):
                regs[k] = (self.reads // (3 + k % 2)) % 2
        elif self.kind == "counters":
            regs = [(self.reads * (k + 1)) & 0xFFFF for k in range(32)]
        else:
            regs = [rnd.randrange(65536) for _ in range(32)]
        return [regs[a - 1] if 1 <= a <= 32 else 0 for a in range(address, address + count)]


def context(kind):
    dev = ModbusDeviceContext(ir=Registers(kind), hr=ModbusSequentialDataBlock(0, [0] * 2200))
    return ModbusServerContext(devices=dev, single=True)


async def main():
    plant = [("127.0.0.1", "bu"), ("127.0.0.2", "flags"), ("127.0.0.3", "counters"), ("127.0.0.4", "random"),
             ("127.0.0.5", "io")]
    servers = [ModbusTcpServer(context(kind), address=(ip, PORT)) for ip, kind in
               (plant[:1] if MODE == "commands" else plant)]
    await asyncio.gather(*(s.serve_forever() for s in servers))

asyncio.run(main())
'''


def _start_capture(path):
    dumpcap = shutil.which("dumpcap")
    if not dumpcap:
        pytest.skip("dumpcap is not installed: cannot capture on lo")
    proc = subprocess.Popen([dumpcap, "-q", "-i", "lo", "-f", "tcp port %d" % PORT, "-w", str(path)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.skip("cannot capture on lo: %s" % proc.stderr.read().strip()[-300:])
        if path.exists() and path.stat().st_size > 0:
            return proc
        time.sleep(0.05)
    proc.kill()
    pytest.skip("cannot capture on lo: dumpcap did not start")


def _stop(proc):
    proc.send_signal(signal.SIGTERM)
    try:
        proc.wait(timeout=10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _client(host):
    from pymodbus.client import ModbusTcpClient
    client = ModbusTcpClient(host, port=PORT, timeout=2)
    deadline = time.monotonic() + 10
    while not client.connect():
        assert time.monotonic() < deadline, "pymodbus server on %s:%d did not come up" % (host, PORT)
        time.sleep(0.1)
    return client


def _output_registers(pco, cao):
    img = bytes([pco, 3, 0, cao]) + b"TO-RU-COMMAND-16" + bytes([0, 0, 0, 0]) + bytes(200)
    return [img[2 * k] | img[2 * k + 1] << 8 for k in range(112)]


def _plc(log):
    """The PLC: every 50 ms read the input image, echo CCI in CAO, write the output image."""
    bu = _client(BU)
    others = {ip: _client(ip) for ip in ORDINARY}
    io = _client(BU_LIKE)
    pco = 1
    end = time.monotonic() + RUN_S
    next_io, count = time.monotonic(), 0
    while time.monotonic() < end:
        if time.monotonic() >= next_io:
            # the IO device, polled as a BU would be, every 100-125 ms
            assert not io.read_input_registers(0, count=32, device_id=1).isError()
            assert not io.write_registers(0, [(count + k) & 0xFFFF for k in range(112)], device_id=1).isError()
            assert not io.readwrite_registers(read_address=2048, read_count=32, write_address=0,
                                              values=[(count + k) & 0xFFFF for k in range(112)],
                                              device_id=1).isError()
            count += 1
            next_io += 0.100 + 0.025 * (count % 2)
        rr = bu.read_input_registers(0, count=32, device_id=1)
        assert not rr.isError(), rr
        regs = list(rr.registers)
        log["read"].append(regs)
        cci = regs[0] >> 8
        wr = bu.write_registers(0, _output_registers(pco, cci), device_id=1)
        assert not wr.isError(), wr
        log["written"].append((pco, cci))
        pco = (pco + 1) & 0xFF
        for client in others.values():
            assert not client.read_input_registers(0, count=32, device_id=1).isError()
        time.sleep(0.05)
    for client in [bu, io] + list(others.values()):
        client.close()


def captured(mode="plant", plc=None):
    """Fixture body: yields (capture path, what the PLC read and wrote) from a
    temporary folder removed afterwards."""
    # readable by tshark when tools/tshark drops root
    folder = Path(tempfile.mkdtemp(prefix="vrshark-realstack-"))
    folder.chmod(0o777)
    try:
        yield _capture(folder, mode, plc)
    finally:
        shutil.rmtree(folder, ignore_errors=True)


@pytest.fixture(scope="module")
def real_capture():
    yield from captured()


def _capture(folder, mode="plant", plc=None, script_text=SERVERS):
    """Runs the servers (mode: "plant" or "commands"; script_text: another
    servers script) and the PLC (default _plc) under dumpcap: (capture path,
    what the PLC read and wrote; "servers": the servers' process)."""
    cap = folder / ("realstack-%s.pcapng" % mode)
    script = folder / "servers.py"
    script.write_text(script_text)
    servers = subprocess.Popen([sys.executable, str(script), str(PORT), mode], stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, text=True)
    log = {"read": [], "written": [], "servers": servers}
    try:
        dumpcap = _start_capture(cap)
        try:
            (plc or _plc)(log)
            time.sleep(0.2)
        finally:
            _stop(dumpcap)
    finally:
        servers.terminate()
        try:
            servers.wait(timeout=10)
        except subprocess.TimeoutExpired:
            servers.kill()
    cap.chmod(0o644)
    return cap, log


PREFS = {"eclink_modbus.port": str(PORT)}
NAMES = ["ip.src", "ip.dst", "modbus.func_code", "eclink.image", "eclink.pci", "eclink.cci", "eclink.bu_state",
         "eclink.eg_link_status", "eclink.ec_link_status", "eclink.armed_ru", "eclink.ru_battery",
         "eclink.joystick1", "eclink.encoder", "eclink.pco", "eclink.cao", "eclink_modbus.accepted_in",
         "frame.time_relative"]


def test_bu_values_match_what_the_plc_read(tshark, real_capture):
    cap, log = real_capture
    assert len(log["read"]) >= 10
    got = tshark.frames(cap, NAMES, prefs=PREFS, two_pass=True)
    inputs = [v for _, v in sorted(got.items()) if v["ip.src"] == BU and v["eclink.image"] == "input"]
    assert len(inputs) == len(log["read"])
    for v, regs in zip(inputs, log["read"]):
        img = b"".join(bytes([r & 0xFF, r >> 8]) for r in regs)
        assert (int(v["eclink.pci"]), int(v["eclink.cci"])) == (img[0], img[1])
        assert int(v["eclink.joystick1"]) == int.from_bytes(img[34:36], "big", signed=True)
        assert (int(v["eclink.bu_state"], 0), int(v["eclink.eg_link_status"]), int(v["eclink.ec_link_status"]),
                int(v["eclink.armed_ru"], 0), int(v["eclink.ru_battery"]), int(v["eclink.encoder"])) == \
            (0x11, 0, 1, 0x4242, 77, 42)
    outputs = [v for _, v in sorted(got.items()) if v["ip.dst"] == BU and v["eclink.image"] == "output"]
    assert [(int(v["eclink.pco"]), int(v["eclink.cao"])) for v in outputs] == log["written"]
    # PCI really moved while the PLC watched
    assert len({r[0] & 0xFF for r in log["read"]}) >= 8


def test_one_pass_as_when_records_kept(tshark, keeping_tshark, real_capture):
    # a one-pass tshark run keeps no per-frame record (lua/vrshark/passes.luam);
    # the same run keeping them shows the same on a real stack's traffic
    cap, _ = real_capture
    args = ["-n", "-r", str(cap), "-o", "eclink_modbus.port:%d" % PORT, "-V"]
    once = tshark.run(args, cache=False).stdout
    assert "EC-Link input image" in once
    assert once == keeping_tshark.run(args, cache=False).stdout


def test_recognized_within_the_first_second(tshark, real_capture):
    cap, _ = real_capture
    got = tshark.frames(cap, NAMES, prefs=PREFS)
    # every client connects from 127.0.0.1: the BU's frames are those between
    # 127.0.0.1 and itself
    bu_frames = {f: v for f, v in got.items() if v["ip.src"] == v["ip.dst"] == BU and v["modbus.func_code"]}
    first = min(bu_frames)
    accepted = {v["eclink_modbus.accepted_in"] for v in bu_frames.values() if v["eclink_modbus.accepted_in"]}
    assert len(accepted) == 1
    acc = int(accepted.pop())
    assert float(got[acc]["frame.time_relative"]) - float(got[first]["frame.time_relative"]) <= 1.0


def test_ordinary_servers_never_decoded(tshark, real_capture):
    cap, _ = real_capture
    for two in (False, True):
        got = tshark.frames(cap, NAMES, prefs=PREFS, two_pass=two)
        polled = [v for v in got.values() if v["ip.src"] in ORDINARY and v["modbus.func_code"]]
        assert len({v["ip.src"] for v in polled}) == 3
        assert [v for v in got.values() if (v["ip.src"] in ORDINARY or v["ip.dst"] in ORDINARY)
                and (v["eclink.image"] or v["eclink_modbus.accepted_in"])] == []


def test_no_modbus_classification_warning(tshark, real_capture):
    cap, _ = real_capture
    out = tshark.run(["-n", "-r", str(cap), "-o", "eclink_modbus.port:%d" % PORT]).stdout
    assert "classify" not in out.lower()
    assert "Query: Trans:" in out and "Response: Trans:" in out


# Wireshark's own Modbus/TCP port preference (mbtcp.tcp.port) and ours
# (eclink_modbus.port, 0 by default: follow mbtcp's): one of them is enough,
# both agree, and mbtcp is never shown a port it cannot classify by.
PORT_SETTINGS = {
    "ours": {"eclink_modbus.port": str(PORT)},
    "wiresharks": {"mbtcp.tcp.port": str(PORT)},
    "both": {"eclink_modbus.port": str(PORT), "mbtcp.tcp.port": str(PORT)},
}


@pytest.mark.parametrize("setting", sorted(PORT_SETTINGS))
def test_either_port_setting_is_enough(tshark, real_capture, setting):
    cap, log = real_capture
    prefs = PORT_SETTINGS[setting]
    out = tshark.run(["-n", "-2", "-r", str(cap)] + sum((["-o", "%s:%s" % kv] for kv in prefs.items()), [])).stdout
    assert "classify" not in out.lower()
    got = tshark.frames(cap, ["ip.src", "eclink.image", "modbus.func_code"], prefs=prefs, two_pass=True)
    inputs = [v for v in got.values() if v["ip.src"] == BU and v["eclink.image"] == "input"]
    assert len(inputs) == len(log["read"]), setting
    # every Modbus/TCP frame classified: a function code on each
    assert all(v["modbus.func_code"] for v in got.values() if v["eclink.image"])


def image_requests(cap, work_dir):
    """Frames of requests that read a whole input image or write an output
    image, as Wireshark's own Modbus/TCP dissector reads them (Decode As on
    the port): the oracle of the note below."""
    fields = ["frame.number", "tcp.dstport", "modbus.func_code", "modbus.reference_num", "modbus.word_cnt",
              "modbus.read_reference_num", "modbus.read_word_cnt", "modbus.write_reference_num",
              "modbus.write_word_cnt"]
    out = subprocess.run(["tshark", "-n", "-r", str(cap), "-o", "mbtcp.tcp.port:%d" % PORT, "-T", "fields"]
                         + sum((["-e", f] for f in fields), []),
                         env={"PATH": "/usr/bin:/bin", "HOME": str(work_dir), "TZ": "UTC",
                              "WIRESHARK_CONFIG_DIR": str(work_dir)}, capture_output=True, text=True).stdout
    found = []
    for line in out.splitlines():
        n, dport, fc, ref, cnt, rref, rcnt, wref, wcnt = (line.split("\t") + [""] * 9)[:9]
        if dport != str(PORT) or not fc:
            continue
        num = lambda v: int(v) if v else -1  # noqa: E731
        fc, ref, cnt = int(fc), num(ref), num(cnt)
        if (fc == 4 and ref == 0 and cnt >= 32) or (fc == 16 and ref == 0 and cnt in (10, 112)) \
                or (fc == 23 and ((num(rref) <= 2048 and num(rref) + num(rcnt) >= 2080)
                                  or (num(wref) == 0 and num(wcnt) in (10, 112)))):
            found.append(int(n))
    return found


def test_neither_port_setting_as_wireshark_alone_but_for_the_note(tshark, real_capture, work_dir):
    """No setting names the port: no EC-Link, and the packet list reads as
    Wireshark's own (the system tshark with its own plugins only), but for
    the requests that read or write a whole image (to the BU, the IO device
    polled like one, the ordinary servers): they say which setting has the
    detection judge their server (never silent). The oracle of which
    requests those are is Wireshark's own Modbus/TCP dissector."""
    cap, _ = real_capture
    args = ["-n", "-r", str(cap), "-T", "fields", "-e", "frame.number", "-e", "frame.protocols",
            "-e", "_ws.col.Info"]
    ours = [line.split("\t") for line in tshark.run(args).stdout.splitlines()]
    alone = [line.split("\t") for line in subprocess.run(
        ["tshark"] + args, env={"PATH": "/usr/bin:/bin", "HOME": str(work_dir), "TZ": "UTC",
                                "WIRESHARK_CONFIG_DIR": str(work_dir)}, capture_output=True, text=True).stdout.splitlines()]
    assert len(ours) == len(alone) > 100
    note = "Modbus/TCP request? to port %d, which is not read as Modbus/TCP [to decode: %%s]" % PORT
    settings = tshark.frames(cap, ["ip.dst", "eclink_modbus.candidate_setting"],
                             display_filter="eclink_modbus.candidate")
    hinted = []
    for o, a in zip(ours, alone):
        if o != a:
            # (Wireshark alone reads some of these requests as rpcap, and fails)
            hinted.append(int(o[0]))
            assert a[1].split(":tcp")[0] == o[1].split(":tcp")[0] and o[1].endswith(":tcp:eclink_modbus:data") \
                and o[2] == note % settings[int(o[0])]["eclink_modbus.candidate_setting"], o
    assert hinted == image_requests(cap, work_dir) and len(hinted) > 30
    assert tshark.frames(cap, ["eclink.image"], display_filter="eclink") == {}
    assert tshark.frames(cap, ["ip.dst", "eclink_modbus.candidate_setting"], display_filter="eclink_modbus.candidate",
                         two_pass=True) == settings
    # each server's first requests (too few for the heuristic) name the server
    # with its port, its later ones the ports with this one: the last note
    # (the report's) decodes under the heuristic, keeping port 502
    port_form = "eclink_modbus.port:502,%d" % PORT
    last = {}
    for n in hinted:
        v = settings[n]
        assert v["eclink_modbus.candidate_setting"] in (port_form, "eclink_modbus.servers:%s:%d" % (v["ip.dst"], PORT))
        last[v["ip.dst"]] = v["eclink_modbus.candidate_setting"]
    assert last == {ip: port_form for ip in [BU, BU_LIKE] + sorted(ORDINARY)}


def test_io_device_polled_like_a_bu_never_decoded(tshark, real_capture):
    """An ordinary IO device whose 0/1 inputs pass every value check of an
    input image, and whose PLC writes a whole output image: not a BU."""
    cap, _ = real_capture
    for two in (False, True):
        got = tshark.frames(cap, NAMES, prefs=PREFS, two_pass=two)
        polled = [v for v in got.values() if BU_LIKE in (v["ip.src"], v["ip.dst"]) and v["modbus.func_code"]]
        assert {v["modbus.func_code"] for v in polled} >= {"4", "16", "23"}
        assert len(polled) >= 40
        assert [v for v in polled if v["eclink.image"] or v["eclink_modbus.accepted_in"]] == []
    # nor any note that it looks like a BU (0/1 inputs, counting registers written)
    notes = tshark.frames(cap, ["ip.src", "ip.dst"], prefs=PREFS, display_filter="eclink_modbus.candidate")
    assert [v for v in notes.values() if BU_LIKE in (v["ip.src"], v["ip.dst"]) or v["ip.src"] in ORDINARY
            or v["ip.dst"] in ORDINARY] == []


# --- a short excerpt of the real capture (editcap -r) ------------------------------

IMAGE_FIELDS = ["eclink.image", "eclink.pci", "eclink.cci", "eclink.cai", "eclink.cmd_from_ru", "eclink.bu_state",
                "eclink.ec_link_status", "eclink.armed_ru", "eclink.ru_battery", "eclink.ru_rssi",
                "eclink.joystick1", "eclink.encoder", "eclink.pco", "eclink.cco", "eclink.cao", "eclink.cmd_to_ru",
                "eclink.periodic_size"]
EXCERPT_NAMES = ["ip.src", "ip.dst", "modbus.func_code", "eclink_modbus.candidate",
                 "eclink_modbus.candidate_setting", "eclink_modbus.accepted_in"] + IMAGE_FIELDS


def _is_bu(v):
    return v["ip.src"] == v["ip.dst"] == BU


@pytest.fixture(scope="module")
def real_excerpt(tshark, real_capture):
    """(excerpt path, first frame of the excerpt in the full capture, the
    full capture decoded in two passes): from a read request of the IO device
    polled like a BU, half-way through, to the response of the BU's second
    input image read after it: two input images and a write of the BU."""
    cap, _ = real_capture
    full = tshark.frames(cap, EXCERPT_NAMES + ["frame.time_relative", "tcp.dstport"], prefs=PREFS, two_pass=True)
    start = min(f for f, v in full.items() if v["ip.dst"] == BU_LIKE and v["modbus.func_code"] == "4"
                and int(v["tcp.dstport"]) == PORT and float(v["frame.time_relative"]) > RUN_S / 2)
    images = [f for f, v in sorted(full.items()) if f > start and _is_bu(v) and v["eclink.image"] == "input"]
    end = images[1]
    assert [f for f in range(start, end) if _is_bu(full[f]) and full[f]["eclink.image"] == "output"]
    excerpt = cap.parent / "excerpt.pcapng"
    subprocess.run(["editcap", "-r", str(cap), str(excerpt), "%d-%d" % (start, end)], check=True)
    excerpt.chmod(0o644)
    return excerpt, start, full


def test_excerpt_unpinned_hint_on_the_bu_alone(tshark, real_excerpt):
    """Too short for the evidence: the BU's image frames carry the note with
    the setting that decodes it; the IO device and the others nothing."""
    excerpt, _, _ = real_excerpt
    setting = "eclink_modbus.servers:%s:%d" % (BU, PORT)
    for two in (False, True):
        got = tshark.frames(excerpt, EXCERPT_NAMES, prefs=PREFS, two_pass=two)
        noted = {f: v for f, v in got.items() if v["eclink_modbus.candidate"]}
        assert len(noted) >= 3                      # two input images and a write
        assert all(_is_bu(v) for v in noted.values())
        assert {v["eclink_modbus.candidate_setting"] for v in noted.values()} == {setting}
        assert [f for f, v in got.items() if v["eclink.image"] or v["eclink_modbus.accepted_in"]] == []
        assert [f for f, v in got.items() if BU_LIKE in (v["ip.src"], v["ip.dst"]) and v["modbus.func_code"]]


@pytest.mark.parametrize("prefs", [{"eclink_modbus.servers": "%s:%d" % (BU, PORT)},
                                   dict(PREFS, **{"eclink_modbus.servers": BU})], ids=["setting-alone", "with-port"])
def test_excerpt_pinned_equals_the_full_capture(tshark, real_excerpt, prefs):
    """The setting the note names (alone, or the address with eclink_modbus.port):
    every image of the BU in the excerpt decoded from its first frame, each
    value equal to the same frame of the whole capture decoded (the oracle);
    the IO device and the other servers stay plain."""
    excerpt, start, full = real_excerpt
    for two in (False, True):
        got = tshark.frames(excerpt, EXCERPT_NAMES, prefs=prefs, two_pass=two)
        decoded = {f: v for f, v in got.items() if v["eclink.image"]}
        assert all(_is_bu(v) for v in decoded.values())
        oracle = {f - start + 1: {k: full[f][k] for k in IMAGE_FIELDS} for f in range(start, start + len(got))
                  if _is_bu(full[f]) and full[f]["eclink.image"]}
        assert sorted(oracle) == sorted(decoded)
        assert {"input", "output"} <= {v["eclink.image"] for v in decoded.values()}
        assert {f: {k: v[k] for k in IMAGE_FIELDS} for f, v in decoded.items()} == oracle
        assert [f for f, v in got.items() if v["eclink_modbus.candidate"]] == []
