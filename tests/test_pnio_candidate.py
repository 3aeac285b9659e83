"""Never silent: a PROFINET run that looked like an MC-MB2-PN base or an
EC-Link BU but whose layout was not inferred carries the note
mcmb2.candidate (Undecoded) and, in mcmb2.candidate_setting, the
mcmb2.layouts entry that decodes it. Frames are built with scapy
(tests/pnio_testlib.py), without a Connect.

- never settled: a base in E010 (its downlink watchdog stalled, so the
  downlink gives no evidence): on the second pass every frame of both
  directions; one pass, where the end of the capture is not known, from the
  frame its uplink showed its evidence (E010, the watchdog moving twice):
  "so far evidence from one direction only";
- given up: the same base whose status then turns undefined: one pass says
  so early as above, then from the frame it was given up in, the second
  pass every frame;
- ambiguous: a downlink header whose base unit number reads as a status
  byte (multiple select), in the PC WORX layout, so that the frames fit the
  two directions the other way round as well: both entries, the
  mcmb2.layout.ambiguous note on the frame that found it;
- the offered setting decodes the run as its Connect does; the ordinary
  devices and public captures never get the note (test_pnio_midsession.py,
  test_mcmb2_public.py: their filters take in mcmb2).
"""
from pnio_testlib import CaptureFile, Device, iocs_first, mac, mcmb2_submodules
from test_pnio_midsession import MCMB2_FIELDS, _slots, _spread

NOTE = ("Looks like an MC-MB2-PN duplex/simplex base, but its layout was not inferred (%s); to decode it now: "
        "%s")
FIELDS = ["mcmb2.candidate_setting", "_ws.expert.message"]


def e010_base(order=None):
    return Device(mcmb2_submodules("duplex", 4, 8, 4, 0, 1), mac(40), 0x8040, 0x8041, order=order)


def e010_traffic(d, cap, pairs, undefined_from=None):
    """The base reports E010 (0x0A, data 0) with its watchdog moving; the
    controller's downlink watchdog stands still."""
    ins, outs = _slots(d, "in"), _slots(d, "out")
    for i in range(pairs):
        status = 0x13 if undefined_from is not None and i >= undefined_from else 0x0A
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([status, i & 0xFF]) + bytes(8))), 0.02)
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([0, 5, 1, 2, 3, 4]))), 0.001)


def build(work_dir, name, device, traffic, connect=False):
    cap = CaptureFile()
    if connect:
        for p in device.connect():
            cap.add(p)
    traffic(device, cap)
    return cap.write(work_dir / name)


def test_a_base_in_e010_never_settles(tshark, work_dir):
    path = build(work_dir, "e010.pcap", e010_base(), lambda d, cap: e010_traffic(d, cap, 30))
    setting = "mcmb2.layouts:0x8040/0x8041=duplex:8/4@4"
    two = tshark.frames(path, FIELDS, two_pass=True)
    want = {"mcmb2.candidate_setting": setting,
            "_ws.expert.message": NOTE % ("not settled by the end of the capture", setting)}
    assert two == {n: want for n in range(1, 61)}
    # one pass: from the uplink's third frame (E010 and its watchdog moved twice) on
    early = {"mcmb2.candidate_setting": setting,
             "_ws.expert.message": NOTE % ("so far evidence from one direction only", setting)}
    assert tshark.frames(path, FIELDS, display_filter="mcmb2.candidate") == {n: early for n in range(5, 61)}
    assert tshark.frames(path, [], display_filter="mcmb2.system", two_pass=True) == {}
    # the setting decodes every frame as the Connect does
    entry = setting.split(":", 1)[1]
    with_connect = build(work_dir, "e010_connect.pcap", e010_base(), lambda d, cap: e010_traffic(d, cap, 30),
                         connect=True)
    a = tshark.frames(with_connect, MCMB2_FIELDS, two_pass=True)
    b = tshark.frames(path, MCMB2_FIELDS, prefs={"mcmb2.layouts": entry}, two_pass=True)
    assert b == {n - 2: row for n, row in a.items() if n > 2}
    assert all(row["mcmb2.system"] == "duplex" for row in b.values())


def test_the_expert_info_is_a_note_of_group_undecoded(tshark, work_dir):
    path = build(work_dir, "e010_expert.pcap", e010_base(), lambda d, cap: e010_traffic(d, cap, 5))
    got = tshark.frames(path, ["_ws.expert.severity", "_ws.expert.group"], display_filter="mcmb2.candidate",
                        two_pass=True)
    # NOTE 0x00400000, PI_UNDECODED 0x05000000
    assert {(r["_ws.expert.severity"], r["_ws.expert.group"]) for r in got.values()} == {("4194304", "83886080")}


def test_given_up_when_the_status_turns_undefined(tshark, work_dir):
    path = build(work_dir, "given_up.pcap", e010_base(iocs_first),
                 lambda d, cap: e010_traffic(d, cap, 30, undefined_from=10))
    # the uplink frame of pair 10 (frame 21) contradicts every uplink reading
    setting = "mcmb2.layouts:0x8040/0x8041=duplex:8/4@4[4d,2c,h,8]"
    want = {"mcmb2.candidate_setting": setting,
            "_ws.expert.message": NOTE % ("its uplink reading was contradicted in frame 21", setting)}
    one = tshark.frames(path, FIELDS, display_filter="mcmb2")
    early = {"mcmb2.candidate_setting": setting,
             "_ws.expert.message": NOTE % ("so far evidence from one direction only", setting)}
    assert one == {n: (early if n < 21 else want) for n in range(5, 61)}
    two = tshark.frames(path, FIELDS, two_pass=True)
    assert two == {n: want for n in range(1, 61)}


def test_a_base_unit_number_that_reads_as_a_status(tshark, work_dir):
    """Multiple select: the controller writes base unit 1, which reads as
    "terminal 0, present"; uplink 20 bytes, downlink 20 data bytes, both
    moving, the PC WORX layout: the frames fit the other way round as well."""
    d = Device(mcmb2_submodules("duplex", 2, 20, 20, 0, 1), mac(41), 0x8042, 0x8043, order=iocs_first)
    ins, outs = _slots(d, "in"), _slots(d, "out")
    cap = CaptureFile()
    for i in range(40):
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x31, i & 0xFF]) + bytes((i + k) % 7 + 1
                                                                                   for k in range(20)))), 0.01)
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([1, (i // 2) & 0xFF]) + bytes(
            (3 * i + k) % 5 + 1 for k in range(20)))), 0.001)
    path = cap.write(work_dir / "base_unit.pcap")
    right = "0x8042/0x8043=duplex:20/20@2[2d,2c,h,20]"
    reversed_ = "0x8043/0x8042=duplex:20/20@2[2d,2c,h,20]"
    ambiguous = tshark.frames(path, ["_ws.expert.message"], display_filter="mcmb2.layout.ambiguous",
                              two_pass=True)
    assert len(ambiguous) == 1
    (at, row), = ambiguous.items()
    entries = sorted([right, reversed_])
    assert ("Layouts that fit these cyclic frames equally: %s or %s; none is decoded until one is left" % (
        tuple(entries) if row["_ws.expert.message"].find(entries[0]) < row["_ws.expert.message"].find(entries[1])
        else tuple(reversed(entries)))) in row["_ws.expert.message"]
    two = tshark.frames(path, ["mcmb2.candidate_setting"], two_pass=True)
    assert {r["mcmb2.candidate_setting"] for r in two.values()} in (
        {"mcmb2.layouts:%s,mcmb2.layouts:%s" % (a, b)} for a, b in ((right, reversed_), (reversed_, right)))
    assert sorted(two) == list(range(1, 81))
    one = tshark.frames(path, [], display_filter="mcmb2.candidate")
    assert sorted(one) == list(range(at, 81))
    # pinning the right one decodes it
    pinned = tshark.frames(path, ["mcmb2.direction"], prefs={"mcmb2.layouts": right}, two_pass=True)
    assert [r["mcmb2.direction"] for n, r in sorted(pinned.items())] == ["uplink", "downlink"] * 40


def pco_standing(work_dir, outlen):
    """An EC-Link BU (DAP of 2) whose PCI moves every 125 ms and whose
    controller keeps PCO at 7: 300 pairs of frames 2 ms apart."""
    from pnio_testlib import eclink_submodules
    from test_pnio_midsession import eclink_image_in, eclink_image_out
    d = Device(eclink_submodules(2, outlen), mac(42), 0x8044, 0x8045)
    cap = CaptureFile()
    for i in range(300):
        cap.add(d.cyclic("in", {1: eclink_image_in((i * 4) // 125)}), 0.002)
        cap.add(d.cyclic("out", {2: eclink_image_out(7, length=outlen)}), 0.002)
    return cap.write(work_dir / ("eclink_pco_standing_%d.pcap" % outlen))


def test_an_eclink_bu_whose_controller_stopped(tshark, work_dir):
    """A Standard BU (224-byte output image): the input image proves the BU
    (its PCI chain); the controller's PCO never moves, so the output image
    gives no evidence (TS-0007 8.4: the BU flags it): the second pass
    names the EC-Link entry; one pass names it from the frame whose PCI
    proved the input image (its third change, pair 64) on."""
    path = pco_standing(work_dir, 224)
    setting = "mcmb2.layouts:0x8044/0x8045=eclink:/224@2"
    two = tshark.frames(path, FIELDS, two_pass=True)
    assert two == {n: {"mcmb2.candidate_setting": setting, "_ws.expert.message": (
        "Looks like an EC-Link BU, but its layout was not inferred (not settled by the end of the capture); "
        "to decode it now: " + setting)} for n in range(1, 601)}
    assert tshark.frames(path, [], display_filter="eclink") == {}
    one = tshark.frames(path, FIELDS, display_filter="mcmb2.candidate")
    assert one == {n: {"mcmb2.candidate_setting": setting, "_ws.expert.message": (
        "Looks like an EC-Link BU, but its layout was not inferred (so far evidence from one direction only); "
        "to decode it now: " + setting)} for n in range(127, 601)}


def test_an_input_and_commands_bu_is_decoded_with_its_pco_standing(tshark, work_dir):
    """The same with a 20-byte output image (Input + Commands, TS-0007 2.1,
    4.3): its controller need not touch PCO (4.1 skips "update PCO"), so the
    pair is recognised from the input image's PCI chain and decoded, no
    candidate note, no PCO stall."""
    path = pco_standing(work_dir, 20)
    two = tshark.frames(path, ["eclink.image", "eclink_pnio.layout_entry"], two_pass=True)
    assert [two[n]["eclink.image"] for n in sorted(two)] == ["input", "output"] * 300
    assert {two[n]["eclink_pnio.layout_entry"] for n in two} == {"0x8044/0x8045=eclink:/20@2"}
    for two_pass in (False, True):
        assert tshark.frames(path, [], display_filter="mcmb2.candidate || eclink_pnio.pco_stalled",
                             two_pass=two_pass) == {}
