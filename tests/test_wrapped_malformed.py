"""The wrapped built-in dissectors (PN-RT under mcmb2/eclink_pnio, mbtcp under
eclink_modbus) may find a packet malformed. Their report stands on its own:
no "Lua Error" on top of it (the fixture fails on one), one pass and -2 agree
on the findings, and the frames after it still decode."""
import pytest

from tools.capgen.frames import TcpConnection
from tools.capgen.pcap import Capture

from conftest import CAPTURES, assert_fields


def _records(path):
    """(timestamp, frame) of a classic pcap written by tools/capgen."""
    import struct
    data = path.read_bytes()
    off, out = 24, []
    while off < len(data):
        sec, usec, caplen, _ = struct.unpack("<IIII", data[off:off + 16])
        out.append((sec + usec / 1e6, data[off + 16:off + 16 + caplen]))
        off += 16 + caplen
    return out


@pytest.fixture
def short_pn_rt(work_dir):
    """The Connect of mcmb2_duplex_connect.pcap, then its first cyclic frame
    cut to 15..24 bytes (PN-RT finds those malformed), then the whole frame."""
    cap = Capture()
    recs = _records(CAPTURES / "mcmb2_duplex_connect.pcap")
    first_cyclic = next(i for i, (_, f) in enumerate(recs) if f[12:14] == b"\x88\x92")
    for _, frame in recs[:first_cyclic]:
        cap.add(0.0, frame)
    frame = recs[first_cyclic][1]
    for cut in (15, 16, 17, 18, 20, 24):
        cap.add(0.1, frame[:cut])
    cap.add(0.1, frame)
    path = work_dir / "pn_short.pcap"
    path.write_bytes(cap.to_bytes())
    path.chmod(0o644)
    return path, first_cyclic


def test_short_pn_rt_frames(tshark, short_pn_rt):
    path, n_connect = short_pn_rt
    frames = tshark.frames(path, ["_ws.malformed", "mcmb2.status"])
    malformed = [n for n, f in frames.items() if f["_ws.malformed"]]
    # PN-RT reports frames cut to 15..20 bytes (and ours stays out); the
    # 24-byte cut passes PN-RT and gets our own "C-SDU too short" finding.
    assert malformed == list(range(n_connect + 1, n_connect + 7))
    last = max(frames)
    for n in range(1, last):
        assert_fields(frames[n], {"mcmb2.status": None}, "frame %d" % n)
    assert_fields(frames[last], {"mcmb2.status": 0}, "the whole frame")
    # Wireshark's own PNIO decoding of the cut frames differs between the
    # passes (it learns from the Connect); ours does not.
    ours = ["frame.number", "mcmb2.status", "mcmb2.uplink_watchdog", "mcmb2.uplink_data"]
    assert tshark.fields(path, ours) == tshark.fields(path, ours, two_pass=True)


def test_malformed_modbus_pdu(tshark, work_dir):
    cap = Capture()
    conn = TcpConnection(cap, "192.168.2.10", 50100, "192.168.2.41", 502)
    conn.handshake(0.0)
    conn.client_send(0.1, bytes.fromhex("000100000006010400000020"))
    conn.server_send(0.103, bytes.fromhex("00010000000401044000"))  # byte count 64, 1 byte
    conn.client_send(0.3, bytes.fromhex("0003000000020110"))        # FC 16 without a body
    path = work_dir / "mb_short.pcap"
    path.write_bytes(cap.to_bytes())
    path.chmod(0o644)
    prefs = {"eclink_modbus.detection": "always"}
    frames = tshark.frames(path, ["_ws.malformed", "modbus.func_code"], prefs=prefs)
    assert [n for n, f in frames.items() if f["_ws.malformed"]] == [6]
    assert "Malformed Packet: Modbus" in frames[6]["_ws.malformed"]
    assert_fields(frames[6], {"modbus.func_code": 16}, "frame 6")
    assert tshark.experts(path, prefs=prefs) == tshark.experts(path, prefs=prefs, two_pass=True)
