"""EC-Link images over PROFINET IO and the handshake analysis."""
import os

import pytest

from conftest import assert_fields

CAP = "eclink_pnio_connect.pcap"


def test_images_from_the_connect(tshark, capture_file):
    cap = capture_file(CAP)
    tshark.expect(cap, 1, {"eclink.image": None, "eclink_pnio.layout": None})
    tshark.expect(cap, 3, {"eclink.image": "input", "eclink.pci": 1, "eclink.cci": 0, "eclink.bu_state": 0x10,
                           "eclink.joystick1": 500, "eclink.joystick2": -250, "eclink.pco": None,
                           "eclink.periodic_size": None, "eclink_pnio.layout": "Connect in frame 1"})
    tshark.expect(cap, 4, {"eclink.image": "output", "eclink.pci": None, "eclink.bu_state": None, "eclink.pco": 1,
                           "eclink.periodic_size": 10, "eclink_pnio.layout": "Connect in frame 1"})


def test_connect_learned(tshark, capture_file):
    ex = tshark.experts(capture_file(CAP))
    assert ex[1] == ["Cyclic data layout learned: eclink device: uplink FrameID 0x8010, downlink FrameID 0x8011"]


def test_cai_timeout_preference(tshark, capture_file):
    """The CAI limit is the project's own preference (TS-0007 8.2 gives none):
    at 100 ms the echo of frame 21, 0.124 s after the command, comes late; in
    one pass and with -2 alike."""
    for two_pass in (False, True):
        ex = tshark.experts(capture_file(CAP), prefs={"eclink_pnio.cai_timeout": "100"}, two_pass=two_pass)
        assert [m for m in ex[21] if "CAI" in m] == [
            "CAI echoed CCO 1 after 0.124 s (limit 0.100 s)",
            "Command to RU (CCO 1 in frame 20) not acknowledged by CAI within 0.100 s"] if not two_pass else [
            "CAI echoed CCO 1 after 0.124 s (limit 0.100 s)"], two_pass
        if two_pass:
            assert ex[20] == ["New command to RU: CCO 0 -> 1",
                              "Command to RU (CCO 1) not acknowledged by CAI within 0.100 s (deadline at frame 21)"]


def test_handshake_experts(tshark, capture_file):
    ex = tshark.experts(capture_file(CAP))
    assert "BU state Disarmed -> Armed" in ex[7]
    assert "New command from RU: CCI 0 -> 1" in ex[9]
    assert "CAO 1 acknowledges the command from RU after 0.251 s" in ex[14]
    assert "New command to RU: CCO 0 -> 1" in ex[20]
    assert "CAI 1 acknowledges the command to RU after 0.124 s" in ex[21]
    assert "PCI 10 has not changed for 0.625 s (limit 0.500 s)" in ex[31]
    assert "New command from RU: CCI 1 -> 2" in ex[43]
    assert "PCO 18 has not changed for 2.125 s (limit 2.000 s): the BU shows \"EC: Bad data\"" in ex[72]
    # one pass: the first frame past the deadline carries the failed command's warning
    assert ex[76] == ["Command from RU (CCI 2 in frame 43) not acknowledged by CAO within 2.000 s: the BU shows \"EC: Bad data\""]
    assert "New command from RU: CCI 1 -> 2" in ex[43] and len(ex[43]) == 1
    # the second pass: on the command, and a note at the deadline
    two = tshark.experts(capture_file(CAP), two_pass=True)
    assert "Command from RU (CCI 2) not acknowledged by CAO within 2.000 s (deadline at frame 76): the BU shows \"EC: Bad data\"" in two[43]
    assert two[76] == ["Deadline of the command from RU (CCI 2) passed with no CAO echo: the BU shows \"EC: Bad data\""]
    stalls = [n for n, m in ex.items() if any("has not changed" in x for x in m)]
    assert stalls == [31, 72]


def test_handshake_frame_links(tshark, capture_file):
    """Frames are named by link fields beside the expert, never by numbers in its text."""
    cap = capture_file(CAP)
    links = ["eclink_pnio.pci_since", "eclink_pnio.pco_since", "eclink_pnio.cmd_from_ru_in",
             "eclink_pnio.cmd_to_ru_in"]
    got = tshark.frames(cap, links, display_filter=" || ".join(links))
    assert list(got) == [14, 21, 31, 72, 76]
    want = {14: {"eclink_pnio.cmd_from_ru_in": 9}, 21: {"eclink_pnio.cmd_to_ru_in": 20},
            31: {"eclink_pnio.pci_since": 21}, 72: {"eclink_pnio.pco_since": 38},
            76: {"eclink_pnio.cmd_from_ru_in": 43}}
    for n, fields in want.items():
        expected = {name: None for name in links}
        expected.update(fields)
        assert_fields(got[n], expected, "frame %d" % n)
    # only a failed command's warning (one pass) names the other frame in its text, the one its link holds
    assert not any("frame" in m for ms in tshark.experts(cap).values() for m in ms
                   if "layout" not in m and "not acknowledged" not in m)
    assert "in frame 43)" in tshark.experts(cap)[76][0]


def test_handshake_severities_and_info_tags(tshark, capture_file):
    cap = capture_file(CAP)
    got = tshark.frames(cap, ["_ws.expert.severity", "_ws.expert.group", "_ws.col.Info"],
                        display_filter="eclink_pnio.pci_stalled || eclink_pnio.pco_stalled")
    assert list(got) == [31, 72]
    for n in (31, 72):
        # PI_ERROR in PI_SEQUENCE (docs/findings.md "How findings read")
        assert_fields(got[n], {"_ws.expert.severity": "8388608", "_ws.expert.group": "33554432"}, "frame %d" % n)
    assert got[31]["_ws.col.Info"].endswith("BU=Armed RU 0x1234=Enabled [PCI stalled 0.625 s]")
    assert got[72]["_ws.col.Info"].endswith("block=0 [PCO stalled 2.125 s]")
    # the deadline of CCI 2 (frame 43) passes at 76: a note and [unacked] there (on every
    # pass, where a live capture shows it), [unacked] on the command
    tshark.expect(cap, 76, {"_ws.col.Info": "Output image PCO=18 CCO=1 CAO=1 size=10 block=0 "
                                            "[PCO stalled 2.375 s] [unacked]"}, two_pass=True)
    tshark.expect(cap, 43, {"_ws.col.Info": "Input image PCI=15 CCI=2 BU=Armed RU 0x1234=Enabled [unacked]",
                            "eclink_pnio.deadline_in": 76}, two_pass=True)
    # ... in one pass the warning and [unacked] at 76, nothing on the command
    tshark.expect(cap, 76, {"_ws.col.Info": "Output image PCO=18 CCO=1 CAO=1 size=10 block=0 "
                                            "[PCO stalled 2.375 s] [unacked]"})
    tshark.expect(cap, 43, {"_ws.col.Info": "Input image PCI=15 CCI=2 BU=Armed RU 0x1234=Enabled",
                            "eclink_pnio.deadline_in": None})
    # ages to the millisecond
    tshark.expect(cap, 31, {"eclink_pnio.pci_age": "0.625000000"})


def test_filters_by_expert_field(tshark, capture_file):
    cap = capture_file(CAP)
    assert list(tshark.frames(cap, [], display_filter="eclink_pnio.cmd_from_ru.late", two_pass=True)) == [43]
    assert list(tshark.frames(cap, [], display_filter="eclink_pnio.cmd_from_ru.deadline", two_pass=True)) == [76]
    tshark.expect(cap, 76, {"eclink_pnio.cmd_from_ru_in": 43, "_ws.expert.message":
                            "Deadline of the command from RU (CCI 2) passed with no CAO echo: the BU shows \"EC: Bad data\""}, two_pass=True)
    # one pass (how CI runs tshark): the warning on the frame past the deadline
    assert list(tshark.frames(cap, [], display_filter="eclink_pnio.cmd_from_ru.late")) == [76]
    assert list(tshark.frames(cap, [], display_filter="eclink_pnio.cmd_from_ru.deadline")) == []
    tshark.expect(cap, 76, {"eclink_pnio.cmd_from_ru_in": 43, "_ws.expert.message":
                            "Command from RU (CCI 2 in frame 43) not acknowledged by CAO within 2.000 s: the BU shows \"EC: Bad data\""})
    warning = "_ws.expert.severity >= warning && eclink_pnio.cmd_from_ru.late"
    assert list(tshark.frames(cap, [], display_filter=warning)) == [76]
    assert list(tshark.frames(cap, [], display_filter=warning, two_pass=True)) == [43]
    for two_pass, text in (([], "Command from RU (CCI 2 in frame 43) not acknowledged by CAO within 2.000 s: "
                                "the BU shows \"EC: Bad data\""),
                           (["-2"], "Command from RU (CCI 2) not acknowledged by CAO within 2.000 s "
                                    "(deadline at frame 76): the BU shows \"EC: Bad data\"")):
        out = tshark.run(["-q", "-n", "-r", str(cap), "-z", "expert,warn"] + two_pass).stdout
        assert [line.split()[0] for line in out.splitlines() if "not acknowledged" in line] == ["1"], out
        assert text in out


def test_two_pass_agrees(tshark, capture_file):
    """All but the command's own "not acknowledged" finding (a forward link),
    which one pass puts on the frame past the deadline, the note's place."""
    fields = ["eclink.pci", "eclink_pnio.pci_age", "_ws.expert.message"]
    one = tshark.frames(capture_file(CAP), fields)
    two = tshark.frames(capture_file(CAP), fields, two_pass=True)
    forward = ",Command from RU (CCI 2) not acknowledged by CAO within 2.000 s (deadline at frame 76): the BU shows \"EC: Bad data\""
    assert forward in two[43]["_ws.expert.message"]
    two[43]["_ws.expert.message"] = two[43]["_ws.expert.message"].replace(forward, "")
    assert one[76]["_ws.expert.message"] == "Command from RU (CCI 2 in frame 43) not acknowledged by CAO within 2.000 s: the BU shows \"EC: Bad data\""
    one[76]["_ws.expert.message"] = "Deadline of the command from RU (CCI 2) passed with no CAO echo: the BU shows \"EC: Bad data\""
    assert one == two
    assert any(r["_ws.expert.message"] for r in one.values())


@pytest.mark.skipif(bool(os.environ.get("VRSHARK_NO_C_PLUGIN")),
                    reason="the profile's rule names EG-Link fields, which need the C plugin")
def test_profile_colours_every_stalled_frame(tshark, capture_file):
    """The vrshark profile's "watchdog stalled" rule marks every frame whose PCI/PCO is past its
    limit (the frames tagged [PCI stalled ...] / [PCO stalled ...]), not only the first."""
    from pathlib import Path
    rules = (Path(__file__).resolve().parents[1] / "profile" / "vrshark" / "colorfilters").read_text()
    rule = next(ln.split("@")[2] for ln in rules.splitlines() if "@vrshark: watchdog stalled@" in ln)
    cap = capture_file(CAP)
    coloured = tshark.frames(cap, [], display_filter="(%s) && eclink_pnio" % rule)
    tagged = [n for n, r in tshark.frames(cap, ["_ws.col.Info"], display_filter="eclink_pnio").items()
              if "stalled" in r["_ws.col.Info"]]
    assert list(coloured) == tagged == [31, 33, 72, 74, 76, 78]


def test_late_echo_reads_late_ack(tshark, work_dir):
    """CAO echoes CCI 2.5 s after the command (scapy-built, with its Connect):
    the command says it is not acknowledged ([unacked], second pass); the
    echo itself reads [late ack] (docs/findings.md "How findings read"), with its own
    expert field."""
    from pnio_testlib import CaptureFile, Device, eclink_submodules, mac
    from test_pnio_midsession import eclink_image_in, eclink_image_out
    d = Device(eclink_submodules(4, 224), mac(21), 0x8030, 0x8031)
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    for i in range(40):            # every 125 ms; CCI 4 from cycle 2, echoed in the output of cycle 22 (2.505 s)
        cci = 4 if i >= 2 else 3
        cao = 4 if i >= 22 else 3
        cap.add(d.cyclic("in", {1: eclink_image_in(i, cci=cci)}), 0.120)
        cap.add(d.cyclic("out", {2: eclink_image_out(i, cao=cao)}), 0.005)
    path = cap.write(work_dir / "late_ack.pcap")
    late = tshark.frames(path, ["_ws.col.Info", "_ws.expert.message"], two_pass=True,
                         display_filter="eclink_pnio.cmd_from_ru.late || eclink_pnio.cmd_from_ru.late_ack")
    (command, echo) = sorted(late)
    assert late[command]["_ws.col.Info"].endswith("CCI=4 BU=Armed RU 0x4242=Enabled [unacked]")
    assert late[echo]["_ws.col.Info"].endswith("[late ack]")
    assert late[echo]["_ws.expert.message"] == "CAO echoed CCI 4 after 2.505 s (limit 2.000 s): the BU shows \"EC: Bad data\""
    tshark.expect(path, echo, {"eclink_pnio.cmd_from_ru.late_ack": True, "eclink_pnio.cmd_from_ru.late": None})
    # one pass: the warning on the first frame past the deadline, before the echo
    one = tshark.frames(path, ["_ws.col.Info", "eclink_pnio.cmd_from_ru_in"],
                        display_filter="eclink_pnio.cmd_from_ru.late || eclink_pnio.cmd_from_ru.late_ack")
    (deadline, echo_one) = sorted(one)
    assert command < deadline < echo_one == echo
    assert one[deadline]["_ws.col.Info"].endswith("[unacked]")
    assert int(one[deadline]["eclink_pnio.cmd_from_ru_in"]) == command


def test_late_echo_first_past_the_deadline(tshark, work_dir):
    """No frame between a command and its echo 2.5 s later (scapy-built): the
    echo is the first frame past the deadline. The second pass says on the
    command that it was not acknowledged in time (deadline at the echo); one
    pass puts that warning on the echo, beside its [late ack], so both count
    the failed command once."""
    from pnio_testlib import CaptureFile, Device, eclink_submodules, mac
    from test_pnio_midsession import eclink_image_in, eclink_image_out
    d = Device(eclink_submodules(4, 224), mac(22), 0x8032, 0x8033)
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    for i in range(4):
        cap.add(d.cyclic("in", {1: eclink_image_in(i, cci=3)}), 0.120)
        cap.add(d.cyclic("out", {2: eclink_image_out(i, cao=3)}), 0.005)
    command = cap.add(d.cyclic("in", {1: eclink_image_in(4, cci=4)}), 0.120)
    echo = cap.add(d.cyclic("out", {2: eclink_image_out(4, cao=4)}), 2.5)
    path = cap.write(work_dir / "late_ack_first.pcap")
    names = ["_ws.col.Info", "_ws.expert.message", "eclink_pnio.cmd_from_ru_in", "eclink_pnio.deadline_in"]
    late = "eclink_pnio.cmd_from_ru.late || eclink_pnio.cmd_from_ru.late_ack"
    two = tshark.frames(path, names, display_filter=late, two_pass=True)
    assert sorted(two) == [command, echo]
    assert two[command]["_ws.col.Info"].endswith("[unacked]")
    assert "Command from RU (CCI 4) not acknowledged by CAO within 2.000 s (deadline at frame %d): the BU shows \"EC: Bad data\"" % echo \
        in two[command]["_ws.expert.message"]
    assert int(two[command]["eclink_pnio.deadline_in"]) == echo
    # (2.5 s without a frame of either stream: the echo also says both stopped)
    assert two[echo]["_ws.col.Info"].endswith("[late ack] [no output 2.620 s] [no input 2.500 s]") \
        and "[unacked]" not in two[echo]["_ws.col.Info"]
    one = tshark.frames(path, names, display_filter=late)
    assert sorted(one) == [echo]
    assert one[echo]["_ws.col.Info"].endswith("[unacked] [late ack] [no output 2.620 s] [no input 2.500 s]")
    assert ("CAO echoed CCI 4 after 2.500 s (limit 2.000 s): the BU shows \"EC: Bad data\","
            "Command from RU (CCI 4 in frame %d) not acknowledged by CAO within 2.000 s: the BU shows \"EC: Bad data\","
            "No output frame (FrameID 0x8033) for 2.620 s since frame %d" % (command, echo - 2)) \
        in one[echo]["_ws.expert.message"]
    assert int(one[echo]["eclink_pnio.cmd_from_ru_in"]) == command
    tshark.expect(path, echo, {"eclink_pnio.cmd_from_ru.late_ack": True, "eclink_pnio.cmd_from_ru.late": True})
    tshark.expect(path, echo, {"eclink_pnio.cmd_from_ru.late_ack": True, "eclink_pnio.cmd_from_ru.late": None},
                  two_pass=True)


def periodic_image(pco, size, block, payload):
    """A standard output image carrying one periodic block (TS-0007 section 8.4:
    size at bytes 20-21, block number at 22, the block's bytes from 24)."""
    img = bytearray(224)
    img[0:4] = bytes([pco & 0xFF, 1, 0, 3])
    img[20:22] = size.to_bytes(2, "big")
    img[22] = block
    chunk = payload[block * 200:(block + 1) * 200]
    img[24:24 + len(chunk)] = chunk
    return bytes(img)


@pytest.mark.parametrize("two_pass", [False, True], ids=["one-pass", "two-pass"])
def test_periodic_blocks_reassembled(tshark, work_dir, two_pass):
    """TS-0007 section 8.4: periodic data over 200 bytes is multiplexed in
    blocks (Periodic data block + size), each block with its own PCO. Over
    PROFINET each block stands in the output image for several cycles (scapy
    frames, with the Connect): each block counts once, the frame of the last
    block carries the 450 bytes, with links to the frames of the blocks and
    from them (the same fields and note as over Modbus/TCP)."""
    from pnio_testlib import CaptureFile, Device, eclink_submodules, mac
    from test_pnio_midsession import eclink_image_in
    d = Device(eclink_submodules(4, 224), mac(23), 0x8034, 0x8035)
    cap = CaptureFile()
    for p in d.connect():
        cap.add(p)
    payload = bytes((i * 7 + 3) & 0xFF for i in range(450))
    first = {}                       # block -> first frame that carries it
    # blocks 0, 1, 2, each for 4 cycles of 32 ms, PCO moving with the block
    for k, block in enumerate([0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2]):
        cap.add(d.cyclic("in", {1: eclink_image_in(k)}), 0.030)
        n = cap.add(d.cyclic("out", {2: periodic_image(10 + block, 450, block, payload)}), 0.002)
        first.setdefault(block, n)
    path = cap.write(work_dir / "periodic.pcap")
    names = ["eclink_pnio.periodic.length", "eclink_pnio.periodic.block_in", "eclink_pnio.periodic.data",
             "eclink_pnio.periodic.reassembled_in", "eclink_pnio.periodic.reassembled", "eclink.periodic_block"]
    got = tshark.frames(path, names, two_pass=two_pass)
    done = first[2]
    assert_fields(got[done], {"eclink_pnio.periodic.length": 450, "eclink.periodic_block": 2,
                              "eclink_pnio.periodic.block_in": [first[0], first[1], first[2]],
                              "eclink_pnio.periodic.data": payload.hex(),
                              "eclink_pnio.periodic.reassembled": True}, "frame %d" % done)
    assert sorted(n for n, r in got.items() if r["eclink_pnio.periodic.data"]) == [done]
    linked = sorted(n for n, r in got.items() if r["eclink_pnio.periodic.reassembled_in"])
    # the link is known once the data is whole: from the first block frames on the second pass
    assert linked == ([first[0], first[1]] if two_pass else [])
    for n in linked:
        assert int(got[n]["eclink_pnio.periodic.reassembled_in"]) == done
    assert "Periodic data reassembled: 450 bytes from 3 blocks" in tshark.experts(path)[done]
