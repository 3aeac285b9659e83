"""PROFINET inference re-opened and then given up is never silent (issue 44
section 4, "never silent"): a layout inferred from the cyclic frames
(lua/vrshark/pnio_infer.luam), re-opened by a contradiction (SP-14-023 2.4:
its downlink watchdog went back), whose frames then fit no layout any more:
both FrameIDs' frames from then on carry the note that the layout was
re-opened and could not be inferred again, naming the re-opening frame and
the settings that decide it (a Connect in the capture, the mcmb2.layouts
entry it had as mcmb2.candidate_setting), in one pass and with -2.

The frames after the contradiction fit no layout because the controller
stopped: every IOPS and IOCS of its downlink frames BAD (0x00, IEC
61158-6-10 IOxS DataState), where every layout the inference knows has a
GOOD (0x80) one. The traffic is test_pnio_reopen.py's stepping traffic,
built with scapy (tests/pnio_testlib.py). The same when the new runs never
settle, given up at the frame limit (vrshark/pnio_infer.luam MAX_FRAMES,
4096 frames of a run), and for an EC-Link BU's layout (TS-0007 4.3),
re-opened by an IOxS neither GOOD nor BAD.
"""
from scapy.layers.l2 import Ether
from scapy.packet import Raw

from pnio_testlib import CaptureFile, Device, eclink_submodules, mac, mcmb2_submodules
from test_eclink_pnio_modes import input_image, output_image
from test_pnio_midsession import _slots, _spread
from test_pnio_reopen import LAYOUT_NOTES, WD_BACK, WRONG, header_after_data, inferred_text, reopened_text

NOTE = "4194304"  # PI_NOTE: the severity of mcmb2.candidate
SETTING = "mcmb2.layouts:" + WRONG
WAIT = ("Not decoded: the layout of this FrameID was re-opened in frame 1552 and is not settled again yet (tshark -2 "
        "or the packet list after loading decodes it with the layout that fits the whole run; mcmb2.layouts pins one)")
NOTE_FIELDS = ["_ws.expert.message", "_ws.expert.severity", "mcmb2.candidate_setting", "mcmb2.layout_entry"]


def given_up_text(reopened, frame):
    return ("Not decoded: layout re-opened in frame %d, not inferred again (given up: no layout fits frame %d); a "
            "Connect in the capture or mcmb2.layouts decides it (it was %s)" % (reopened, frame, SETTING))


def stopping_capture(work_dir, name, stop):
    """test_pnio_reopen.stepping_traffic without the Connect (the downlink
    data module before its header: the wrong layout settles in frame 102,
    its watchdog goes back in frame 1552), the controller stopped from pair
    `stop` on: every IOxS byte of its downlink frames 0x00 (BAD) instead of
    0x80 (GOOD). Pair i is frames 2i+1 (uplink) and 2i+2 (downlink)."""
    d = Device(mcmb2_submodules("duplex", 2, 2, 2, 0, 1), mac(0x44), 0x8441, 0x8442, order=header_after_data)
    cap = CaptureFile()
    ins, outs = _slots(d, "in"), _slots(d, "out")
    for i in range(1000):
        wd_up, wd_down = (i // 10) & 0xFF, (i // 25) & 0xFF
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x31, wd_up, 0x11, (i // 40) % 50 + 1]))), 0.001)
        down = d.cyclic("out", _spread(outs, "outlen", bytes([0, wd_down, 6, wd_down % 31 + 1])))
        if i >= stop:
            raw = bytearray(bytes(down))
            # Ethernet 14, FrameID 2, C-SDU 40: no data byte is 0x80 (watchdogs < 40)
            raw[16:56] = raw[16:56].replace(b"\x80", b"\x00")
            down = down.__class__(bytes(raw))
        cap.add(down, 0.001)
    return cap.write(work_dir / ("%s.pcap" % name))


def notes_after(tshark, path, first, **kw):
    got = tshark.frames(path, NOTE_FIELDS, display_filter="frame.number >= %d" % first, **kw)
    assert len(got) == 2001 - first
    return got


def row(text, setting=""):
    return {"_ws.expert.message": text, "_ws.expert.severity": NOTE, "mcmb2.candidate_setting": setting,
            "mcmb2.layout_entry": ""}


def test_given_up_after_the_re_opening_is_said(tshark, work_dir):
    """Issue 44 section 4 (never silent) and SP-14-023 2.4: the layout
    settled in frame 102 is re-opened in frame 1552 (its watchdog went
    back); the controller stops from pair 790 (frame 1582, its IOxS BAD),
    and the downlink run, fitting no layout there, is given up, the uplink
    run with it (it cannot settle without its pair). One pass: until then
    the note that the layout is not settled again yet, from frame 1582 on,
    on both FrameIDs, the note that it could not be inferred again, with
    the entry it had (mcmb2.candidate_setting); -2: that note on every frame
    since the re-opening. The re-opening frame keeps its warning."""
    path = stopping_capture(work_dir, "stop_after", 790)
    layout_notes = {102: [inferred_text(1, 102, WRONG)], 1552: [reopened_text(102, 1552, WD_BACK)]}
    for two_pass in (False, True):
        assert tshark.experts(path, display_filter=LAYOUT_NOTES, two_pass=two_pass) == layout_notes
    given_up = row(given_up_text(1552, 1582), SETTING)
    one = notes_after(tshark, path, 1553)
    assert all(one[n] == row(WAIT) for n in range(1553, 1582)), "not settled again yet, until the give-up"
    assert all(one[n] == given_up for n in range(1582, 2001)), "both FrameIDs, from the give-up on"
    two = notes_after(tshark, path, 1553, two_pass=True)
    assert all(two[n] == given_up for n in range(1553, 2001))
    # the setting offered is the filter that finds them
    found = tshark.frames(path, ["mcmb2.candidate_setting"], display_filter='mcmb2.candidate_setting == "%s"'
                          % SETTING)
    assert sorted(found) == list(range(1582, 2001))


def test_given_up_on_the_re_opening_frame(tshark, work_dir):
    """Issue 44 section 4: the frame that re-opens the layout (SP-14-023
    2.4: its downlink watchdog went back, frame 1552) fits no layout itself
    (the controller stopped from that pair: IOxS BAD), so the new downlink
    run is given up on its first frame, and the uplink run, starting only
    after it, at once: every frame after 1552 says so, in one pass and -2;
    frame 1552 keeps its warning."""
    path = stopping_capture(work_dir, "stop_at", 775)
    for two_pass in (False, True):
        notes = tshark.experts(path, display_filter=LAYOUT_NOTES, two_pass=two_pass)
        assert notes == {102: [inferred_text(1, 102, WRONG)], 1552: [reopened_text(102, 1552, WD_BACK)]}
        got = notes_after(tshark, path, 1553, two_pass=two_pass)
        assert all(got[n] == row(given_up_text(1552, 1552), SETTING) for n in range(1553, 2001)), two_pass


def standing_capture(work_dir, name, pairs):
    """stopping_capture's traffic with the controller running, but from
    the re-opening frame on (pair 775, frame 1552: the wrong layout's
    watchdog went back) both stations repeat that pair's C-SDUs: neither
    watchdog moves again, nor any data (the base and the controller
    stalled, the base still reporting "terminal present", no E010), so
    every layout of the new runs still fits and none is proven."""
    d = Device(mcmb2_submodules("duplex", 2, 2, 2, 0, 1), mac(0x44), 0x8441, 0x8442, order=header_after_data)
    cap = CaptureFile()
    ins, outs = _slots(d, "in"), _slots(d, "out")
    for i in range(776):
        wd_up, wd_down = (i // 10) & 0xFF, (i // 25) & 0xFF
        up = d.cyclic("in", _spread(ins, "inlen", bytes([0x31, wd_up, 0x11, (i // 40) % 50 + 1])))
        down = d.cyclic("out", _spread(outs, "outlen", bytes([0, wd_down, 6, wd_down % 31 + 1])))
        cap.add(up, 0.001)
        cap.add(down, 0.001)
    # (the same frames as bytes, each with its own cycle counter: the
    # APDU status, the last 4 bytes, starts with it; scapy builds slowly)
    frozen = [(p[Ether].src, p[Ether].dst, bytearray(bytes(p[Ether].payload))) for p in (up, down)]
    for _ in range(776, pairs):
        for src, dst, raw in frozen:
            d.cycle = (d.cycle + 32) & 0xFFFF
            raw[-4:-2] = d.cycle.to_bytes(2, "big")
            cap.add(Ether(src=src, dst=dst, type=0x8892) / Raw(bytes(raw)), 0.001)
    return cap.write(work_dir / ("%s.pcap" % name))


def test_given_up_past_the_frame_limit_after_the_re_opening(tshark, work_dir):
    """Issue 44 section 4 (never silent) and SP-14-023 2.4: the layout
    settled in frame 102 is re-opened in frame 1552 (its watchdog went
    back); from then on nothing moves (standing_capture), so the new runs
    neither settle nor lose their last layout. The downlink run, started by
    the re-opening frame itself, is given up on its 4096th frame, frame
    9742 (vrshark/pnio_infer.luam MAX_FRAMES = 4096: a run not settled
    within 4096 frames is given up), 8190 frames after the re-opening, and
    the uplink run with it. One pass: the note that the layout is not
    settled again yet up to frame 9741 (frame 9740, the run's 4095th,
    still waits), from 9742 on, on both FrameIDs, the note that it could
    not be inferred again, naming the limit and the entry it had
    (mcmb2.candidate_setting); -2: that note on every frame since the
    re-opening, whose frame keeps its warning."""
    path = standing_capture(work_dir, "standing", 4900)
    layout_notes = {102: [inferred_text(1, 102, WRONG)], 1552: [reopened_text(102, 1552, WD_BACK)]}
    for two_pass in (False, True):
        assert tshark.experts(path, display_filter=LAYOUT_NOTES, two_pass=two_pass) == layout_notes
    given_up = row("Not decoded: layout re-opened in frame 1552, not inferred again (given up: not settled within "
                   "4096 frames, at frame 9742); a Connect in the capture or mcmb2.layouts decides it (it was %s)"
                   % SETTING, SETTING)
    fields = dict(display_filter="frame.number > 1552")
    one = tshark.frames(path, NOTE_FIELDS, **fields)
    assert len(one) == 9800 - 1552
    assert all(one[n] == row(WAIT) for n in range(1553, 9742)), "not settled again yet, up to the limit"
    assert all(one[n] == given_up for n in range(9742, 9801)), "both FrameIDs, from the give-up on"
    two = tshark.frames(path, NOTE_FIELDS, two_pass=True, **fields)
    assert all(two[n] == given_up for n in range(1553, 9801))
    # the setting offered is the filter that finds them
    found = tshark.frames(path, ["mcmb2.candidate_setting"], display_filter='mcmb2.candidate_setting == "%s"'
                          % SETTING)
    assert sorted(found) == list(range(9742, 9801))


ECLINK_NOTES = LAYOUT_NOTES + " || eclink_pnio.layout.inferred || eclink_pnio.layout.reopened"


def eclink_capture(work_dir, name, outlen, pairs, pco_stands=None, stop=None):
    """An EC-Link BU (TS-0007 4.3: slot 1 "Inputs" 64 bytes, slot 2 an
    output image of `outlen` bytes) without its Connect, one input and one
    output frame a cycle (125 ms), its PCI stepping every cycle: the layout
    settles in frame 6. The DAP's IOPS of pair 20's input frame (frame 41)
    is 0x81, neither GOOD nor BAD (IEC 61158-6-10 IOxS); the controller
    stops from pair `stop` on (every IOxS of its output frames BAD, 0x00);
    pco_stands: the pair from which the PCO of a 224-byte output image
    stands. Pair i is frames 2i+1 (input) and 2i+2 (output)."""
    d = Device(eclink_submodules(4, outlen), mac(0x60), 0x8060, 0x8061)
    cap = CaptureFile()
    for i in range(pairs):
        up = d.cyclic("in", {1: input_image(i, 0, 0)})
        if i == 20:
            raw = bytearray(bytes(up))
            raw[16] = 0x81  # Ethernet 14, FrameID 2: the C-SDU's first byte, the DAP's IOPS
            up = up.__class__(bytes(raw))
        cap.add(up, 0.124)
        pco = i if pco_stands is None else min(i, pco_stands)
        down = d.cyclic("out", {2: output_image(0, 0) if outlen == 20 else bytes([pco & 0xFF]) + bytes(223)})
        if stop is not None and i >= stop:
            raw = bytearray(bytes(down))
            # the C-SDU (no image byte is 0x80), not the APDU status
            raw[16:-4] = raw[16:-4].replace(b"\x80", b"\x00")
            down = down.__class__(bytes(raw))
        cap.add(down, 0.001)
    return cap.write(work_dir / ("%s.pcap" % name))


def eclink_layout_notes(entry):
    return {6: ["Cyclic data layout inferred from frames 1..6 (no Connect in the capture); to pin it, add to "
                "mcmb2.layouts: %s" % entry],
            41: ["Layout inferred from frames 1..6 contradicted in frame 41: IOPS of slot 0/0x1 is 0x81, neither "
                 "GOOD nor BAD; inference re-opened (was %s)" % entry]}


def eclink_notes(tshark, path, entry, want):
    """The layout notes of eclink_capture() (frames 6 and 41), and on each
    frame after the re-opening, none decoded, the note want(two_pass, n)."""
    for two_pass in (False, True):
        assert tshark.experts(path, display_filter=ECLINK_NOTES, two_pass=two_pass) == eclink_layout_notes(entry)
        got = tshark.frames(path, NOTE_FIELDS + ["eclink.image"], display_filter="frame.number > 41",
                            two_pass=two_pass)
        assert list(got) == list(range(42, 81))
        for n, fields in got.items():
            assert fields == dict(want(two_pass, n), **{"eclink.image": ""}), (two_pass, n)


def test_eclink_given_up_after_the_re_opening_is_said(tshark, work_dir):
    """Issue 44 section 4 (never silent), EC-Link over PROFINET (TS-0007
    4.3): the BU's layout (Input + Commands, a 20-byte output image),
    inferred in frame 6, is re-opened in frame 41 (an IOPS neither GOOD
    nor BAD, IEC 61158-6-10: the runs start again from the next frame);
    the controller stops from pair 22 (frame 46, its IOxS BAD) before the
    runs settle again, and both are given up. One pass: the note that the
    layout is not settled again yet on frames 42..45, from 46 on, on both
    FrameIDs, the note that it could not be inferred again, with the entry
    it had (mcmb2.candidate_setting: EC-Link's frames carry MC-MB2-PN's
    candidate note, the layout table is one); -2: that note on every frame
    after the re-opening, whose frame keeps its warning (mcmb2's, as the
    frame is not decoded again by a layout settled again)."""
    entry = "0x8060/0x8061=eclink:/20@4"
    setting = "mcmb2.layouts:" + entry
    path = eclink_capture(work_dir, "eclink_stop", 20, 40, stop=22)
    wait = WAIT.replace("frame 1552", "frame 41")
    given_up = row("Not decoded: layout re-opened in frame 41, not inferred again (given up: no layout fits frame "
                   "46); a Connect in the capture or mcmb2.layouts decides it (it was %s)" % setting, setting)
    eclink_notes(tshark, path, entry, lambda two_pass, n: given_up if two_pass or n >= 46 else row(wait))
    found = tshark.frames(path, ["mcmb2.candidate_setting"], display_filter='mcmb2.candidate_setting == "%s"'
                          % setting)
    # (frame 5: the one-direction note before the layout first settled)
    assert sorted(found) == [5] + list(range(46, 81))


def test_eclink_given_up_after_its_input_image_proved(tshark, work_dir):
    """Issue 44 section 4 (never silent), EC-Link over PROFINET: the BU's
    layout (Standard, a 224-byte output image), inferred in frame 6, is
    re-opened in frame 41 (an IOPS neither GOOD nor BAD); its PCO stands
    from then on, so the output run gives no evidence, while the input
    image's PCI chain proves the input run (frame 47): the pair then looks
    like an EC-Link BU from one direction (docs/profinet.md "Looks like
    ours"), and when the controller stops (pair 30, frame 62: its IOxS
    BAD) the runs are given up as one that looked like ours: one pass, the
    note that the layout is not settled again yet on 42..46, the one-
    direction note on 47..61, from 62 on the given-up note with the entry
    that decodes it; -2: that note on every frame after the re-opening,
    whose frame keeps its warning. Never silent; the note is the one of a
    run that looked like ours, not that of the re-opening."""
    entry = "0x8060/0x8061=eclink:/224@4"
    setting = "mcmb2.layouts:" + entry
    path = eclink_capture(work_dir, "eclink_pco_stands", 224, 40, pco_stands=20, stop=30)
    wait = row(WAIT.replace("frame 1552", "frame 41"))
    looks = "Looks like an EC-Link BU, but its layout was not inferred (%s); to decode it now: " + setting
    early = row(looks % "so far evidence from one direction only", setting)
    given_up = row(looks % "given up: no layout fits frame 62", setting)
    eclink_notes(tshark, path, entry, lambda two_pass, n: given_up if two_pass or n >= 62 else early if n >= 47
                 else wait)
