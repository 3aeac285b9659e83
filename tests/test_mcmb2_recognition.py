"""Recognising MC-MB2-PN and EC-Link devices in traffic the project did not
make: frames and PNIO-CM Connects built with scapy's PROFINET layers
(tests/pnio_testlib.py), not tools/capgen.

- A polled base without its Connect whose downlink has ASCII modules
  (SP-14-023 section 5.3: per terminal, data modules then ASCII modules):
  its uplink carries one IOCS per downlink module, more than Z split into
  data modules alone gives, and the downlink is laid out by the split of Z
  whose IOPS positions hold IOxS values.
- The layout table naming ASCII modules (`a8`), and a polled entry without
  sizes.
- Connects for duplex, polled and EC-Link devices, with FrameIDs in the
  request and FrameIDs the device assigns in the response.
"""
from pnio_testlib import E010, CaptureFile, Device, eclink_submodules, mac, mcmb2_submodules


def polled_device(index=1, dap=4, up=6, data=2, ascii_=8, terminals=2, in_fid=0x8001, out_fid=0xC001):
    return Device(mcmb2_submodules("polled", dap, up, data, ascii_, terminals), mac(index), in_fid, out_fid)


def uplink(d, status=0x0F, wd=1, y=6, z=10, slots=(0x11, 0x21, 0x0F, 0x0F), payloads=(b"\x01" * 6, b"\x02" * 6)):
    """{slot: bytes} of a polled uplink: header in slot 1, then each terminal's Y bytes."""
    data = {1: bytes([status, wd, y, z] + list(slots))}
    rest = b"".join(payloads)
    for s in sorted((s for s in d.subs if s.slot > 1 and s.inlen), key=lambda s: s.slot):
        data[s.slot], rest = rest[:s.inlen], rest[s.inlen:]
    return data


def downlink(d, wd=1, payloads=(b"\x11\x12" + b"HELLO-01", b"\x21\x22" + b"HELLO-02")):
    """{slot: bytes} of a polled downlink: reserved + watchdog, then each terminal's Z bytes."""
    first = min(s.slot for s in d.subs if s.outlen)
    data = {first: bytes([0, wd])}
    rest = b"".join(payloads)
    for s in sorted((s for s in d.subs if s.slot > first and s.outlen), key=lambda s: s.slot):
        data[s.slot], rest = rest[:s.outlen], rest[s.outlen:]
    return data


def polled_capture(work_dir, name, d, downs=None):
    cap = CaptureFile()
    cap.add(d.cyclic("in", uplink(d)))
    for i, payloads in enumerate(downs or [None]):
        cap.add(d.cyclic("out", downlink(d, wd=1 + i) if payloads is None else downlink(d, 1 + i, payloads)))
        cap.add(d.cyclic("in", uplink(d, wd=2 + i)))
    return cap.write(work_dir / name)


def test_polled_header_with_ascii_downlink_modules(tshark, work_dir):
    """Z = 10 as a 2-byte data module and an 8-byte ASCII module: 1 + 2 x 2
    IOCS bytes in the uplink, where data modules alone (one 10-byte module)
    would give 1 + 2 x 1. Before, the frame stayed raw PNIO."""
    path = polled_capture(work_dir, "ascii.pcap", polled_device())
    for two_pass in (False, True):
        tshark.expect(path, 1, {"mcmb2.system": "polled", "mcmb2.layout": "polled header in frame 1",
                                "mcmb2.uplink_size": 6, "mcmb2.downlink_size": 10, "mcmb2.slot.terminal": [1, 2, 0, 0],
                                "mcmb2.slot.uplink_data": ["010101010101", "020202020202"],
                                "_ws.expert.message": None}, two_pass=two_pass)
        tshark.expect(path, 2, {"mcmb2.system": "polled", "mcmb2.direction": "downlink",
                                "mcmb2.layout": "polled header in frame 1", "mcmb2.downlink_watchdog": 1,
                                "mcmb2.slot": [1, 2], "mcmb2.slot.downlink_data": [
                                    (b"\x11\x12HELLO-01").hex(), (b"\x21\x22HELLO-02").hex()],
                                "_ws.expert.message": None}, two_pass=two_pass)
        tshark.expect(path, 3, {"mcmb2.uplink_watchdog": 2, "mcmb2.layout": "polled header in frame 1"},
                      two_pass=two_pass)


def test_polled_header_ascii_only_and_many_dap(tshark, work_dir):
    """Z = 40 of ASCII alone (one 40-byte module, no data module gives 40) and 8 DAP submodules."""
    d = polled_device(dap=8, data=0, ascii_=40, terminals=1)
    cap = CaptureFile()
    cap.add(d.cyclic("in", uplink(d, z=40, slots=(0x0F, 0x31, 0x0F, 0x0F), payloads=(b"\x05" * 6,))))
    cap.add(d.cyclic("out", downlink(d, payloads=(b"A" * 40,))))
    path = cap.write(work_dir / "ascii40.pcap")
    tshark.expect(path, 1, {"mcmb2.layout": "polled header in frame 1", "mcmb2.downlink_size": 40,
                            "mcmb2.slot.uplink_data": "050505050505"})
    tshark.expect(path, 2, {"mcmb2.direction": "downlink", "mcmb2.slot": 2, "mcmb2.slot.downlink_data": "41" * 40})


def test_downlink_split_settles_on_a_later_frame(tshark, work_dir):
    """Z = 10 as 2 data + 8 ASCII. The first downlink holds 0x80 where the
    4 + 6 split would put an IOPS, so two splits fit it; the next frame
    tells them apart, and both frames are laid out as 2 + 8 in one pass and
    in two."""
    d = polled_device()
    look_alike = (b"\x11\x12" + b"\x80\x80\x80\x80\x80\x80\x80\x80", b"\x21\x22" + b"\x80\x80\x80\x80\x80\x80\x80\x80")
    path = polled_capture(work_dir, "settle.pcap", d, downs=[look_alike, None])
    for two_pass in (False, True):
        tshark.expect(path, 4, {"mcmb2.direction": "downlink", "mcmb2.slot.downlink_data": [
            (b"\x11\x12HELLO-01").hex(), (b"\x21\x22HELLO-02").hex()], "_ws.expert.message": None},
            two_pass=two_pass)
        tshark.expect(path, 2, {"mcmb2.direction": "downlink", "mcmb2.slot": [1, 2]}, two_pass=two_pass)


def test_layout_table_names_ascii_modules(tshark, work_dir):
    """0x8001/0xC001=polled:2x6/2x2,a8: the table names the ASCII module."""
    path = polled_capture(work_dir, "table.pcap", polled_device())
    prefs = {"mcmb2.layouts": "0x8001/0xC001=polled:2x6/2x2,a8@4", "mcmb2.heuristic": "FALSE"}
    tshark.expect(path, 1, {"mcmb2.layout": "preference", "mcmb2.slot.uplink_data": ["010101010101", "020202020202"],
                            "_ws.expert.message": None}, prefs=prefs)
    tshark.expect(path, 2, {"mcmb2.layout": "preference", "mcmb2.slot.downlink_data": [
        (b"\x11\x12HELLO-01").hex(), (b"\x21\x22HELLO-02").hex()], "_ws.expert.message": None}, prefs=prefs)
    # The same sizes as data modules only (one 10-byte module) do not fit the frames.
    wrong = {"mcmb2.layouts": "0x8001/0xC001=polled:2x6/2x10@4", "mcmb2.heuristic": "FALSE"}
    tshark.expect(path, 2, {"mcmb2.layout": "preference", "mcmb2.slot.downlink_data": [
        (b"\x11\x12\x80HELLO-0").hex(), (b"\x80\x21\x22\x80HELLO-").hex()]}, prefs=wrong)


def test_layout_table_polled_without_sizes(tshark, work_dir):
    """A polled entry without sizes takes them from the header, even with the heuristic off."""
    path = polled_capture(work_dir, "table-nosizes.pcap", polled_device())
    prefs = {"mcmb2.layouts": "0x8001/0xC001=polled", "mcmb2.heuristic": "FALSE"}
    tshark.expect(path, 1, {"mcmb2.layout": "preference, sizes from the polled header in frame 1"}, prefs=prefs)
    tshark.expect(path, 2, {"mcmb2.layout": "preference, sizes from the polled header in frame 1",
                            "mcmb2.slot.downlink_data": [(b"\x11\x12HELLO-01").hex(), (b"\x21\x22HELLO-02").hex()]},
                  prefs=prefs)


def connect_capture(work_dir, name, d, request_fids, frames):
    cap = CaptureFile()
    req, res = d.connect(request_fids=request_fids)
    cap.add(req)
    cap.add(res)
    for direction, data in frames:
        cap.add(d.cyclic(direction, data))
    return cap.write(work_dir / name)


def test_connect_duplex_frame_ids_from_the_response(tshark, work_dir):
    """Duplex, 20 + 4 uplink, 10 data + 20 ASCII downlink; the request leaves both FrameIDs to the device."""
    d = Device(mcmb2_submodules("duplex", 2, 24, 10, 20, 1), mac(7), 0x8123, 0x8124)
    up = {1: bytes([0x31, 9]), 2: b"\x07" * 20, 3: b"\x08" * 4}
    down = {4: bytes([3, 9]), 5: b"\x01" * 10, 6: b"text for terminal 1!"}
    path = connect_capture(work_dir, "duplex.pcap", d, (0xFFFF, 0xFFFF), [("in", up), ("out", down)])
    tshark.expect(path, 1, {"mcmb2.system": "duplex", "mcmb2.frame_id": None, "_ws.expert.message":
                            "Cyclic data layout learned: duplex device: uplink FrameID assigned in the response, "
                            "downlink FrameID assigned in the response"})
    tshark.expect(path, 2, {"mcmb2.system": "duplex", "mcmb2.frame_id": [0x8123, 0x8124]})
    tshark.expect(path, 3, {"mcmb2.layout": "Connect in frame 1", "mcmb2.status": 1, "mcmb2.terminal": 3,
                            "mcmb2.uplink_data": "07" * 20 + "08" * 4, "_ws.expert.message": None})
    tshark.expect(path, 4, {"mcmb2.layout": "Connect in frame 1", "mcmb2.base_unit": 3,
                            "mcmb2.downlink_data": "01" * 10 + b"text for terminal 1!".hex()})


def test_connect_polled_with_ascii(tshark, work_dir):
    """Polled, 2 terminals, 2 data + 8 ASCII downlink; FrameIDs in the request."""
    d = polled_device(index=8)
    path = connect_capture(work_dir, "polled.pcap", d, None,
                           [("in", uplink(d, status=0x0A)), ("out", downlink(d))])
    tshark.expect(path, 2, {"mcmb2.system": "polled", "mcmb2.frame_id": [0x8001, 0xC001]})
    tshark.expect(path, 3, {"mcmb2.layout": "Connect in frame 1", "mcmb2.status": 0xA,
                            "mcmb2.slot.uplink_data": ["010101010101", "020202020202"], "_ws.expert.message": E010})
    tshark.expect(path, 4, {"mcmb2.layout": "Connect in frame 1", "mcmb2.slot.downlink_data": [
        (b"\x11\x12HELLO-01").hex(), (b"\x21\x22HELLO-02").hex()]})


def test_connect_eclink_frame_id_from_the_response(tshark, work_dir):
    """EC-Link BU (64-byte input image, 224-byte output image); the device assigns the input FrameID."""
    d = Device(eclink_submodules(3, 224), mac(9), 0x8200, 0xC200)
    image = bytearray(64)
    image[0], image[20] = 11, 3  # PCI 11, BU state 3
    path = connect_capture(work_dir, "eclink.pcap", d, (0xFFFF, 0xC200),
                           [("in", {1: bytes(image)}), ("out", {2: bytes([5]) + bytes(223)})])
    assert tshark.experts(path)[2] == ["IOCRBlockRes: input frameID changed from 65535 to 33280!",  # Wireshark's
                                       "Cyclic data layout learned: eclink device: uplink FrameID 0x8200, "
                                       "downlink FrameID 0xc200"]
    tshark.expect(path, 3, {"eclink_pnio.layout": "Connect in frame 1", "eclink.image": "input", "eclink.pci": 11})
    tshark.expect(path, 4, {"eclink_pnio.layout": "Connect in frame 1", "eclink.image": "output", "eclink.pco": 5})
