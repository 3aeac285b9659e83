"""A Connect request too large for one DCE/RPC datagram (a base with many
submodules) is sent as fragments: each datagram carries the fragment flag,
its fragment number and the same activity and sequence number, the last
one the last-fragment flag. The carrier puts them together (in whatever
order they arrive) and learns the layout from the whole request, on the
frame that completes it; every cyclic frame then reads as with the
Connect in one datagram. One pass and two agree; a Connect whose last
fragment is missing teaches nothing and the frames go to the inference."""
import struct

import pytest
from scapy.layers.inet import IP, UDP
from scapy.layers.l2 import Ether
from scapy.packet import Raw

from pnio_testlib import CaptureFile, Device, mac, mcmb2_submodules
from test_pnio_midsession import _slots, _spread

FIELDS = ["mcmb2.system", "mcmb2.direction", "mcmb2.status", "mcmb2.uplink_watchdog", "mcmb2.downlink_watchdog",
          "mcmb2.slot.uplink_data", "mcmb2.slot.downlink_data", "_ws.expert.message"]
FRAG, LASTFRAG = 0x04, 0x02


def fragments(pkt, size):
    """The DCE/RPC datagram of pkt cut into fragments of `size` body bytes,
    as a controller sends a large Connect (fragment numbers from 0)."""
    rpc = bytes(pkt[UDP].payload)
    head, body = bytearray(rpc[:80]), rpc[80:]
    fmt = "<H" if head[4] & 0x10 else ">H"
    chunks = [body[i:i + size] for i in range(0, len(body), size)]
    out = []
    for n, chunk in enumerate(chunks):
        h = bytearray(head)
        h[2] |= FRAG | (LASTFRAG if n == len(chunks) - 1 else 0)
        h[74:76] = struct.pack(fmt, len(chunk))
        h[76:78] = struct.pack(fmt, n)
        out.append(Ether(src=pkt[Ether].src, dst=pkt[Ether].dst)
                   / IP(src=pkt[IP].src, dst=pkt[IP].dst, id=pkt[IP].id + n)
                   / UDP(sport=pkt[UDP].sport, dport=pkt[UDP].dport) / Raw(bytes(h) + chunk))
    return out


def traffic(d, cap, cycles=8):
    ins, outs = _slots(d, "in"), _slots(d, "out")
    for i in range(cycles):
        up = bytes([0x01, (i + 1) & 0xFF]) + bytes((7 * i + k) & 0x7F for k in range(26))
        cap.add(d.cyclic("in", _spread(ins, "inlen", up)), 0.004)
        down = bytes([0, (i + 1) & 0xFF]) + bytes((3 * i + k) & 0x7F for k in range(10)) + b"HOIST01 " * 2 + b"HOIS"
        cap.add(d.cyclic("out", _spread(outs, "outlen", down)), 0.004)


def capture(work_dir, name, order=None, size=None, drop_last=False):
    """The Connect request whole (size None) or in fragments of `size` body
    bytes sent in `order` (fragment numbers; default in order), its
    response, then the cyclic frames. Returns (path, frames before the
    cyclic ones)."""
    d = Device(mcmb2_submodules("duplex", 4, 26, 10, 20, 1), mac(60), 0x8060, 0x8061)
    req, res = d.connect()
    cap = CaptureFile()
    parts = [req] if size is None else fragments(req, size)
    if size is not None:
        assert len(parts) >= 3
        if drop_last:
            parts = parts[:-1]
        parts = [parts[i] for i in (order or range(len(parts)))]
    for p in parts:
        cap.add(p)
    cap.add(res)
    traffic(d, cap)
    return cap.write(work_dir / name), len(parts) + 1


@pytest.mark.parametrize("two_pass", [False, True])
@pytest.mark.parametrize("order", [None, (2, 0, 3, 1)], ids=["in_order", "out_of_order"])
def test_fragmented_connect_reads_as_whole(tshark, work_dir, two_pass, order):
    whole, n0 = capture(work_dir, "connect_whole.pcap")
    frag, n1 = capture(work_dir, "connect_frags.pcap", order=order, size=160)
    assert n1 == 5
    a = tshark.frames(whole, FIELDS + ["mcmb2.layout"], two_pass=two_pass)
    b = tshark.frames(frag, FIELDS + ["mcmb2.layout"], two_pass=two_pass)
    cyclic = [n for n in a if n > n0]
    assert len(cyclic) == 16
    for n in cyclic:
        row = b[n - n0 + n1]
        assert {k: row[k] for k in FIELDS} == {k: a[n][k] for k in FIELDS}, n
        assert a[n]["mcmb2.layout"] == "Connect in frame 1"
        # learned on the frame that completes the request (its last fragment to arrive)
        assert row["mcmb2.layout"] == "Connect in frame 4"
    assert a[n0 + 1]["mcmb2.system"] == "duplex" and a[n0 + 1]["mcmb2.direction"] == "uplink"
    note = tshark.frames(frag, ["_ws.expert.message", "pn_io.block_type"], two_pass=two_pass)
    assert "Cyclic data layout learned" in note[4]["_ws.expert.message"]
    for k in (1, 2, 3):
        assert "layout learned" not in note[k]["_ws.expert.message"]
    # the oracle: Wireshark's own DCE/RPC reassembles the same fragments
    # into the Connect request on the same frame (our fragments are real ones)
    assert note[4]["pn_io.block_type"] == "0x0101,0x0102,0x0102,0x0103,0x0104"
    assert all(note[k]["pn_io.block_type"] == "" for k in (1, 2, 3))


def test_connect_without_its_last_fragment(tshark, work_dir):
    """The last fragment lost: no Connect to learn from; the duplex base's
    frames are inferred from their own bytes instead (not from a Connect)."""
    frag, n1 = capture(work_dir, "connect_no_last.pcap", size=160, drop_last=True)
    got = tshark.frames(frag, ["mcmb2.layout", "_ws.expert.message"], two_pass=True)
    assert not any("Connect in frame" in row["mcmb2.layout"] for row in got.values())
    assert not any("layout learned" in row["_ws.expert.message"] for row in got.values())
    assert any(row["mcmb2.layout"].startswith("inferred") for n, row in got.items() if n > n1)
