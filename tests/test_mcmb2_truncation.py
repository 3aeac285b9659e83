"""PROFINET frames of our systems cut at every length: Wireshark's PN-RT
report or our own finding, never a Lua error (the fixture fails on one). The
polled-header recognition must not read past a short C-SDU."""
import struct

import pytest

from tools.capgen.pcap import Capture

from conftest import CAPTURES


def _frames(name):
    data = (CAPTURES / name).read_bytes()
    off, out = 24, []
    while off < len(data):
        _, _, caplen, _ = struct.unpack("<IIII", data[off:off + 16])
        out.append(data[off + 16:off + 16 + caplen])
        off += 16 + caplen
    return out


@pytest.mark.parametrize("name", ["mcmb2_polled_noconnect.pcap", "mcmb2_polled_vlan.pcap",
                                  "mcmb2_duplex_connect.pcap", "eclink_pnio_noconnect.pcap"])
def test_every_cut_of_the_first_cyclic_frame(tshark, work_dir, name):
    frames = _frames(name)
    first = next(i for i, f in enumerate(frames) if b"\x88\x92" in f[12:18])
    cap = Capture()
    for f in frames[:first]:
        cap.add(0.0, f)
    for cut in range(15, len(frames[first])):
        cap.add(0.001 * cut, frames[first][:cut])   # a short frame, as captured
    path = work_dir / ("cut-" + name)
    path.write_bytes(cap.to_bytes())
    path.chmod(0o644)
    rows = tshark.fields(path, ["frame.number", "_ws.col.Protocol"])
    assert len(rows) == len(frames[:first]) + len(frames[first]) - 15
    tshark.verbose(path)
    tshark.verbose(path, two_pass=True)
