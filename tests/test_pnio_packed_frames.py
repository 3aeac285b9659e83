"""What the PROFINET carrier keeps per frame is packed into strings once the
capture has moved past a chunk of 1,024 frames (lua/vrshark/framemap.luam):
the second pass (tshark -2, a click in Wireshark) reads the frames of such
chunks back from those strings. Scapy-built captures of 3,000 frames, so that
the first two chunks are packed, with findings, links and ages in them."""
import pytest

from conftest import assert_fields


def eclink_capture(work_dir):
    """An EC-Link BU with its Connect, 1,500 cycles of 8 ms: PCI moves every
    125 ms but stalls for 0.7 s from cycle 200 on, a command from the RU at
    cycle 100 is echoed 2.5 s late (cycle 412), one at cycle 1300 in time."""
    from pnio_testlib import CaptureFile, Device, eclink_submodules, mac
    from test_pnio_midsession import eclink_image_in, eclink_image_out
    d = Device(eclink_submodules(4, 224), mac(31), 0x8040, 0x8041)
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    frames = {}
    for i in range(1500):
        pci = (i * 8) // 125
        if 200 <= i < 290:
            pci = (200 * 8) // 125
        cci = 5 if i >= 100 else 4
        cci = 6 if i >= 1300 else cci
        cao = 4
        if i >= 412:
            cao = 5
        if i >= 1310:
            cao = 6
        frames[("in", i)] = cap.add(d.cyclic("in", {1: eclink_image_in(pci, cci=cci)}), 0.004)
        frames[("out", i)] = cap.add(d.cyclic("out", {2: eclink_image_out(i // 12, cao=cao)}), 0.004)
    return cap.write(work_dir / "packed_eclink.pcap"), frames


def test_eclink_second_pass_reads_packed_chunks(tshark, work_dir):
    path, frames = eclink_capture(work_dir)
    fields = ["eclink.pci", "eclink.pco", "eclink_pnio.pci_age", "eclink_pnio.pco_age", "eclink_pnio.cmd_from_ru_in",
              "eclink_pnio.deadline_in", "_ws.col.Info", "_ws.expert.message"]
    one = tshark.frames(path, fields)
    two = tshark.frames(path, fields, two_pass=True)
    assert len(one) == len(two) == 3002
    command, echo = frames[("in", 100)], frames[("out", 412)]
    assert command < 1024 and echo < 1024 < frames[("in", 600)] < 2048
    # the command (chunk 0) gets its forward finding and link on the second pass only
    assert "Command from RU (CCI 5) not acknowledged by CAO within 2.000 s (deadline at frame" in two[command]["_ws.expert.message"]
    assert two[command]["_ws.col.Info"].endswith("[unacked]")
    assert two[command]["eclink_pnio.deadline_in"] != ""
    deadline = int(two[command]["eclink_pnio.deadline_in"])
    for n in (command, deadline):
        one.pop(n)
        two.pop(n)
    assert one == two
    # an age in a packed chunk, exact: PCI became 12 at cycle 188 (1504 ms // 125),
    # so at cycle 289 it has kept it for 101 cycles of 8 ms
    stalled = frames[("in", 289)]
    assert_fields(two[stalled], {"eclink.pci": 12, "eclink_pnio.pci_age": "0.808000000"}, "frame %d" % stalled)
    assert_fields(two[echo], {"eclink_pnio.cmd_from_ru_in": command}, "frame %d" % echo)
    assert two[echo]["_ws.col.Info"].endswith("[late ack]")
    assert any("PCI 12 has not changed" in r["_ws.expert.message"] for r in two.values())


def mcmb2_capture(path, index, cycle):
    """An MC-MB2-PN duplex base (26 bytes up, 10 down) with its Connect,
    1,500 cycles of 4 ms; cycle(i) gives the uplink and downlink data
    (header included) of cycle i. Returns the path and the frame numbers by
    ("up" or "down", cycle)."""
    from pnio_testlib import CaptureFile, Device, mac, mcmb2_submodules
    from test_pnio_midsession import _slots, _spread
    d = Device(mcmb2_submodules("duplex", 1, 26, 10, 0, 1), mac(index), 0x8002 + 2 * index, 0x8003 + 2 * index)
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    ins, outs = _slots(d, "in"), _slots(d, "out")
    frames = {}
    for i in range(1500):
        up, down = cycle(i)
        frames[("up", i)] = cap.add(d.cyclic("in", _spread(ins, "inlen", up)), 0.002)
        frames[("down", i)] = cap.add(d.cyclic("out", _spread(outs, "outlen", down)), 0.002)
    return cap.write(path), frames


def test_mcmb2_second_pass_reads_packed_chunks(tshark, work_dir):
    """An MC-MB2-PN duplex base: the uplink watchdog stops for 1.2 s at
    cycle 700 and the status is E010 for cycles 1000-1009."""
    def cycle(i):
        wd = 700 if 700 <= i < 1000 else i
        e010 = 1000 <= i < 1010
        return (bytes([0x1A if e010 else 0x11, wd & 0xFF]) + (bytes(26) if e010 else bytes(range(1, 27))),
                bytes([1, (i // 2) & 0xFF]) + bytes(10))
    path, frames = mcmb2_capture(work_dir / "packed_mcmb2.pcap", 32, cycle)
    fields = ["mcmb2.status", "mcmb2.uplink_watchdog", "mcmb2.watchdog_age", "_ws.col.Info", "_ws.expert.message"]
    one = tshark.frames(path, fields)
    two = tshark.frames(path, fields, two_pass=True)
    assert len(two) == 3002
    assert one == two
    e010 = frames[("up", 1000)]
    assert 1024 < e010 < 2048
    assert_fields(two[e010], {"mcmb2.status": 0x0A}, "frame %d" % e010)
    assert "[E010]" in two[e010]["_ws.col.Info"]
    assert any("Uplink watchdog unchanged" in r["_ws.expert.message"] for r in two.values())


def test_mcmb2_watchdog_ages_kept_beside_shared_records(tshark, work_dir):
    """A base whose watchdogs move every 100 ms (uplink) and 60 ms (downlink)
    at a 4 ms cycle: the ages take 25 and 15 values, more than the 8 recent
    records a frame is compared with, so the carrier keeps them per frame
    (packed, beside the shared record) and puts them back when a frame is
    shown. Exact ages in a packed chunk; one pass and -2 agree."""
    path, frames = mcmb2_capture(work_dir / "packed_mcmb2_ages.pcap", 33, lambda i: (
        bytes([0x11, (i // 25) & 0xFF]) + bytes(range(1, 27)), bytes([1, (i // 15) & 0xFF]) + bytes(10)))
    fields = ["mcmb2.uplink_watchdog", "mcmb2.downlink_watchdog", "mcmb2.watchdog_age", "mcmb2.watchdog_ms",
              "_ws.col.Info", "_ws.expert.message"]
    one = tshark.frames(path, fields)
    two = tshark.frames(path, fields, two_pass=True)
    assert len(two) == 3002
    assert one == two
    up, down = frames[("up", 1210)], frames[("down", 1217)]
    assert 1024 < up < down < 3072
    # uplink watchdog 48 since cycle 1200, downlink 81 since cycle 1215
    assert_fields(two[up], {"mcmb2.uplink_watchdog": 48, "mcmb2.watchdog_age": "0.040000000",
                            "mcmb2.watchdog_ms": 40}, "frame %d" % up)
    assert_fields(two[down], {"mcmb2.downlink_watchdog": 81, "mcmb2.watchdog_age": "0.008000000",
                              "mcmb2.watchdog_ms": 8}, "frame %d" % down)
    ages = {two[frames[("up", i)]]["mcmb2.watchdog_ms"] for i in range(1100, 1200)}
    assert ages == {str(4 * k) for k in range(25)}


if __name__ == "__main__":
    pytest.main([__file__])
