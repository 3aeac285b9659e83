"""PROFINET inference never settles silently on a wrong layout (issue 44
section 4): evidence that contradicts a layout inferred from the cyclic
frames (lua/vrshark/pnio_infer.luam) re-opens the inference, with a note
naming the frame and the evidence, and tshark -2 decodes the whole run with
the layout that fits it.

The evidence (SP-14-023):
- a watchdog that goes back: "This watchdog counter is incremented by the
  MC-MB2-PN" (3.1.2), "shall be incremented by the IO-Controller" (3.2.2,
  2.4); an 8-bit counter wraps 255 -> 0, and 0 -> 1 goes on, anything else
  backwards contradicts the layout;
- the base unit number (3.2.1) written by the controller as configuration,
  so it does not move from frame to frame;
- an IOxS byte that is neither GOOD (0x80) nor BAD (0x00, 0x20, 0x40, 0x60).

The frames are built with scapy (tests/pnio_testlib.py); the oracle is the
decode of the same traffic with its Connect (test_pnio_frame_layouts.py).
"""
import random

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pnio_testlib import DATA_MODULES, CaptureFile, Device, largest_first, mac, mcmb2_submodules
from test_pnio_frame_layouts import captures, module_kinds, order_from
from test_pnio_midsession import MCMB2_FIELDS, _slots, _spread

FIELDS = ["mcmb2.base_unit", "mcmb2.downlink_watchdog", "mcmb2.downlink_data", "mcmb2.uplink_watchdog",
          "mcmb2.uplink_data"]


def header_after_data(direction, elements):
    """The controller put the downlink data module before the downlink
    header (any frame offsets are legal: the IOCR block's)."""
    if direction != "out":
        return elements
    out = list(elements)
    data = [i for i, e in enumerate(out) if e[0] == "data"]
    out[data[0]], out[data[1]] = out[data[1]], out[data[0]]
    return out


def stepping_traffic(d, cap, pairs, first_byte=lambda i: 6, bad_iops_pair=None):
    """A duplex base, 2 bytes up and 2 down: the downlink data module is
    [first_byte(i), wd % 31 + 1], so its second byte steps with the downlink
    watchdog wd (every 25 cycles) and goes back from 31 to 1 when wd reaches
    31 (pair 775, frame 1552 without the Connect). bad_iops_pair: the pair
    whose uplink frame has 0x81 for the DAP's first IOPS."""
    ins, outs = _slots(d, "in"), _slots(d, "out")
    for i in range(pairs):
        wd_up, wd_down = (i // 10) & 0xFF, (i // 25) & 0xFF
        up = d.cyclic("in", _spread(ins, "inlen", bytes([0x31, wd_up, 0x11, (i // 40) % 50 + 1])))
        if i == bad_iops_pair:
            raw = bytearray(bytes(up))
            raw[16] = 0x81  # Ethernet 14, FrameID 2: the C-SDU's first byte, the DAP's IOPS
            up = up.__class__(bytes(raw))
        cap.add(up, 0.001)
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([0, wd_down, first_byte(i), wd_down % 31 + 1]))),
                0.001)


def stepping_captures(work_dir, name="stepping", order=header_after_data, pairs=1000, **kw):
    paths = []
    for connect in (True, False):
        d = Device(mcmb2_submodules("duplex", 2, 2, 2, 0, 1), mac(0x44), 0x8441, 0x8442, order=order)
        cap = CaptureFile()
        if connect:
            for p in d.connect():
                cap.add(p)
        stepping_traffic(d, cap, pairs, **kw)
        paths.append(cap.write(work_dir / ("%s_%s.pcap" % ("with" if connect else "without", name))))
    return paths


WRONG = "0x8441/0x8442=duplex:2/2@2"
RIGHT = "0x8441/0x8442=duplex:2/2@2[/2d,2c,2,h]"
LAYOUT_NOTES = "mcmb2.layout.inferred || mcmb2.layout.reopened"


def reopened_text(settled, frame, why, entry=WRONG):
    return "Layout inferred from frames 1..%d contradicted in frame %d: %s; inference re-opened (was %s)" % (
        settled, frame, why, entry)


def inferred_text(first, last, entry, at=None):
    return ("Cyclic data layout inferred from frames %d..%d (no Connect in the capture%s); to pin it, add to "
            "mcmb2.layouts: %s" % (first, last, ", re-opened in frame %d" % at if at else "", entry))


WD_BACK = "downlink watchdog went back 31 -> 1 (SP-14-023 2.4: only incremented, 255 wraps to 0)"


def test_a_data_module_stepping_with_the_watchdog_is_not_the_header(tshark, work_dir):
    """SP-14-023 3.2.1/3.2.2: the downlink header is the base unit number
    (0 here) and the downlink watchdog. A 2-byte data module placed before
    it whose second byte steps with the watchdog fits as a header until its
    "watchdog" goes back (31 -> 1, not a wrap 255 -> 0): -2 decodes every
    frame as with the Connect (base unit 0, the true watchdog)."""
    with_connect, without = stepping_captures(work_dir)
    a = tshark.frames(with_connect, MCMB2_FIELDS + FIELDS, two_pass=True)
    b = tshark.frames(without, MCMB2_FIELDS + FIELDS, two_pass=True)
    assert len(b) == 2000
    for n, row in b.items():
        assert row == a[n + 2], "frame %d" % n
    # downlink frames: even numbers; pair i is frames 2i+1, 2i+2
    assert b[2]["mcmb2.base_unit"] == "0" and b[2]["mcmb2.downlink_watchdog"] == "0"
    assert b[1552]["mcmb2.base_unit"] == "0" and b[1552]["mcmb2.downlink_watchdog"] == "31"
    assert b[1551]["mcmb2.uplink_watchdog"] == "77"


def test_the_contradiction_is_said_by_frame(tshark, work_dir):
    """Issue 44 section 4: evidence that contradicts a settled layout
    re-opens the inference "and says so with a note (expert info, naming the
    frame and the evidence)". One pass: the wrong layout decodes until the
    frame that contradicts it (SP-14-023 2.4: its watchdog went back), the
    frames after it are not decoded until the layout settles again, then
    decode with the new layout; -2: the whole run with the new one."""
    _, without = stepping_captures(work_dir)
    after = {1552: [reopened_text(102, 1552, WD_BACK)], 1652: [inferred_text(1552, 1652, RIGHT, 1552)]}
    assert tshark.experts(without, display_filter=LAYOUT_NOTES) == {102: [inferred_text(1, 102, WRONG)], **after}
    assert tshark.experts(without, display_filter=LAYOUT_NOTES, two_pass=True) == after
    one = tshark.frames(without, ["mcmb2.base_unit", "mcmb2.downlink_watchdog", "mcmb2.layout_entry"])
    assert one[1550] == {"mcmb2.base_unit": "6", "mcmb2.downlink_watchdog": "31", "mcmb2.layout_entry": WRONG}
    assert all(one[n] == {"mcmb2.base_unit": "", "mcmb2.downlink_watchdog": "", "mcmb2.layout_entry": ""}
               for n in range(1552, 1652)), "not decoded while re-opened"
    # ... and not in silence: each of those frames says why and what decodes it
    notes = tshark.frames(without, ["_ws.expert.message", "_ws.expert.severity"], display_filter="frame.number > 1552 "
                          "&& frame.number < 1652")
    assert {tuple(r.values()) for r in notes.values()} == {(
        "Not decoded: the layout of this FrameID was re-opened in frame 1552 and is not settled again yet (tshark -2 "
        "or the packet list after loading decodes it with the layout that fits the whole run; mcmb2.layouts pins "
        "one)", "4194304")}
    assert len(notes) == 99
    assert one[1654] == {"mcmb2.base_unit": "0", "mcmb2.downlink_watchdog": "33", "mcmb2.layout_entry": RIGHT}
    two = tshark.frames(without, ["mcmb2.layout_entry"], two_pass=True)
    assert {r["mcmb2.layout_entry"] for r in two.values()} == {RIGHT}


def test_a_base_unit_number_that_moves(tshark, work_dir):
    """SP-14-023 3.2.1: the base unit number is written by the IO controller
    as configured; the one a settled layout reads moving (a data byte, 6 then
    7 from pair 500) re-opens the inference in that frame, before the
    watchdog it reads goes back; -2 decodes as with the Connect."""
    with_connect, without = stepping_captures(work_dir, "base_unit", first_byte=lambda i: 6 if i < 500 else 7)
    why = "base unit number moved 6 -> 7 (SP-14-023 3.2.1: configuration)"
    notes = tshark.experts(without, display_filter=LAYOUT_NOTES, two_pass=True)
    assert notes == {1002: [reopened_text(102, 1002, why)], 1102: [inferred_text(1002, 1102, RIGHT, 1002)]}
    a = tshark.frames(with_connect, MCMB2_FIELDS + FIELDS, two_pass=True)
    b = tshark.frames(without, MCMB2_FIELDS + FIELDS, two_pass=True)
    assert all(row == a[n + 2] for n, row in b.items())
    assert b[1002]["mcmb2.base_unit"] == "0" and b[1002]["mcmb2.downlink_data"] == "0715"


def test_an_iops_neither_good_nor_bad(tshark, work_dir):
    """IEC 61158-6-10 IOxS: DataState GOOD is 0x80, BAD 0x00/0x20/0x40/0x60
    (by subslot, slot, device, controller); 0x81 (the extension bit) in a
    byte a settled layout reads as an IOPS re-opens the inference from the
    next frame (that frame cuts no layout), and the same layout settles again
    (nothing else fits): the frame says so; -2 decodes every frame as with
    the Connect, that one too."""
    with_connect, without = stepping_captures(work_dir, "iops", order=None, bad_iops_pair=300)
    entry = "0x8441/0x8442=duplex:2/2@2"
    why = "IOPS of slot 0/0x1 is 0x81, neither GOOD nor BAD"
    notes = tshark.experts(without, display_filter=LAYOUT_NOTES, two_pass=True)
    assert notes == {601: [reopened_text(102, 601, why, entry), "IOPS of slot 0/0x1 is not GOOD (0x81)"],
                     702: [inferred_text(602, 702, entry, 601)]}
    a = tshark.frames(with_connect, MCMB2_FIELDS + FIELDS, two_pass=True)
    b = tshark.frames(without, MCMB2_FIELDS + FIELDS, two_pass=True)
    assert all(row == a[n + 2] for n, row in b.items())


# -- any legal layout (hypothesis) ---------------------------------------------
def harsh_traffic(d, cap, pairs, up, data, seed):
    """Traffic that tempts the inference: every 2-byte data module of the
    base (up and down) holds [a byte whose low nibble is a legal status,
    wd % k + 1], stepping with that direction's watchdog and going back
    when it wraps at k; other data random (not 0x80); the ASCII modules
    letters; base unit number 0 (SP-14-023 3.2.1)."""
    rnd = random.Random(seed)
    ins, outs = _slots(d, "in"), _slots(d, "out")
    ndata = len(largest_first(data, DATA_MODULES))
    k_up, k_down = rnd.randint(3, 20), rnd.randint(3, 20)
    byte = lambda: rnd.choice([b for b in range(1, 256) if b != 0x80])  # noqa: E731
    fixed_up = [byte() for _ in range(up)]
    fixed_down = [byte() for _ in range(data)]

    def fill(subs, sizes, wd, k, fixed, first):
        out, pos = [], 0
        for s in subs:
            n = sizes(s)
            if n == 2 and first.get(s.slot) is not None:
                out += [first[s.slot], wd % k + 1]
            else:
                out += [b if rnd.random() < 0.8 else byte() for b in fixed[pos:pos + n]]
            pos += n
        return bytes(out)

    first_up = {s.slot: rnd.choice([0x11, 0x21, 0x02]) for s in ins[1:] if s.inlen == 2}
    first_down = {s.slot: rnd.choice([6, 0x11, 0x31]) for s in outs[1:1 + ndata] if s.outlen == 2}
    ascii_ = sum(s.outlen for s in outs[1:]) - data
    for i in range(pairs):
        wd_up, wd_down = (i // 3) & 0xFF, (i // 5) & 0xFF
        payload = fill(ins[1:], lambda s: s.inlen, wd_up, k_up, fixed_up, first_up)
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x31, wd_up]) + payload)), 0.002)
        down = fill(outs[1:1 + ndata], lambda s: s.outlen, wd_down, k_down, fixed_down, first_down)
        down += (b"CRANEHOIST" * 64)[:ascii_]
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([0, wd_down]) + down)), 0.002)


def header_after_two(which):
    """Slot order, but the header after the last 2-byte data module in the
    uplink ("in"), the downlink ("out") or both."""
    def order(direction, elements):
        out = list(elements)
        if which in (direction, "both"):
            data = [i for i, e in enumerate(out) if e[0] == "data" and
                    (e[1].inlen if direction == "in" else e[1].outlen) == 2 and e[1].slot > 0]
            if len(data) >= 2:
                h = out.pop(data[0])
                out.insert(data[-1], h)
        return out
    return order


duplex_config = st.tuples(st.just("duplex"), st.integers(1, 8), st.sampled_from([2, 4, 6, 12, 22, 26]),
                          st.sampled_from([2, 4, 6, 12]), st.sampled_from([0, 2, 8, 20]))


@settings(max_examples=10, deadline=None, database=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(cfg=duplex_config, perms=st.fixed_dictionaries({"in": st.permutations(range(40)),
                                                        "out": st.permutations(range(40))}),
       swap=st.sampled_from([None, "in", "out", "both"]), seed=st.integers(0, 2 ** 16))
def test_never_a_silent_wrong_layout(tshark, work_dir, cfg, perms, swap, seed):
    """Issue 44 section 4, "never a silent wrong layout": any legal duplex
    layout (SP-14-023 5.3; DAP subslots 1..8; the IOCR's frame offsets in
    any order, both CRs) with the Connect cut and 2-byte data modules that
    step with the watchdog: with -2 every frame decodes as with the Connect,
    or is not decoded and carries a note whose mcmb2.layouts entry decodes
    it so. A frame decoded otherwise is a silent wrong decode. swap: the
    usual order but for the header after a 2-byte data module (the order
    that made a data module pass for the header), else any order."""
    system, dap, up, data, ascii_ = cfg
    subs = mcmb2_submodules("duplex", dap, up, data, ascii_, 1)
    probe = Device(subs, mac(0x4400), 0x8443, 0x8444)
    assert len(probe.subs) <= 40
    order = order_from(perms, module_kinds(cfg, probe)) if swap is None else header_after_two(swap)
    name = "harsh-%d" % len(list(work_dir.glob("with_harsh-*")))
    with_connect, without = captures(
        work_dir, name, lambda: Device(subs, mac(0x4400), 0x8443, 0x8444, order=order),
        lambda d, cap: harsh_traffic(d, cap, 150, up, data, seed))
    fields = MCMB2_FIELDS + FIELDS
    a = tshark.frames(with_connect, fields, two_pass=True)
    b = tshark.frames(without, fields, two_pass=True)
    wrong = [n for n, row in b.items() if row != a[n + 2]]
    if not wrong:
        return
    decoded_wrong = [n for n in wrong if any(b[n][f] for f in fields if f != "_ws.col.Info")]
    assert not decoded_wrong, "silent wrong decode in frames %s" % decoded_wrong[:10]
    offered = tshark.frames(without, ["mcmb2.candidate_setting"], two_pass=True)
    settings_ = {s for n in wrong for s in offered[n]["mcmb2.candidate_setting"].split(",") if s}
    assert settings_, "frames %s not decoded and no entry offered" % wrong[:10]
    for s in sorted(settings_):
        pinned = tshark.frames(without, fields, prefs={"mcmb2.layouts": s.split(":", 1)[1]}, two_pass=True)
        if all(row == a[n + 2] for n, row in pinned.items()):
            return
    raise AssertionError("no entry offered (%s) decodes as with the Connect" % sorted(settings_))


def test_what_the_frames_cannot_tell_is_in_the_tree(tshark, work_dir):
    """Issue 44 section 4: same-size modules whose order the frames cannot
    tell are said in the tree, with the setting that decides it. SP-14-023
    5.3: 40 uplink bytes are two 20-byte modules (which is which: only the
    Connect), and a downlink of 8 data bytes then 8 ASCII bytes where both
    hold text: the later is taken for ASCII, a mcmb2.layouts entry's frame
    order decides it."""
    d = Device(mcmb2_submodules("duplex", 2, 40, 8, 8, 1), mac(0x45), 0x8451, 0x8452)
    cap = CaptureFile()
    ins, outs = _slots(d, "in"), _slots(d, "out")
    for i in range(100):
        cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x31, i // 5]) + bytes(range(1, 41)))), 0.002)
        cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([0, i // 5]) + b"ABCDEFGH" + b"HOIST OK")), 0.002)
    path = cap.write(work_dir / "order.pcap")
    got = tshark.frames(path, ["mcmb2.layout_entry", "mcmb2.layout_order"], two_pass=True)
    assert {tuple(r.values()) for r in got.values()} == {(
        "0x8451/0x8452=duplex:40/8,a8@2",
        "order of 2 uplink modules of 20 bytes taken in frame order (only the Connect tells); which downlink "
        "module of 8 bytes is ASCII taken as the later (both or neither hold text): the frame order of a "
        "mcmb2.layouts entry decides it (a8 where the ASCII one sits)")}


def test_a_text_like_data_module_next_to_ascii(tshark, work_dir):
    """Issue 44 section 4, issue 54 item 1: when two layouts fit, the one
    that keeps the frame order is taken and the other offered. SP-14-023
    5.3: the downlink holds the data modules, then the ASCII modules, each
    of a size the catalogue has. A 4-byte data module holding "PUMP" before
    a 20-byte ASCII module fits two ways: 4 data + 20 ASCII (the modules in
    frame order, what the Connect says) or 24 ASCII bytes (20 + 4: the text
    taken for ASCII, against the frame order). The tree says which it took
    and offers the other as a mcmb2.layouts setting, the settling note too;
    either entry decodes every frame as with the Connect, the bytes in
    frame order."""
    subs = mcmb2_submodules("duplex", 2, 2, 4, 20, 1)

    def traffic(d, cap):
        ins, outs = _slots(d, "in"), _slots(d, "out")
        for i in range(100):
            cap.add(d.cyclic("in", _spread(ins, "inlen", bytes([0x31, i // 5, 0x11, 0x22]))), 0.002)
            cap.add(d.cyclic("out", _spread(outs, "outlen", bytes([0, i // 5]) + b"PUMP" + b"CRANE HOIST NUMBER 1")),
                    0.002)

    with_connect, without = captures(work_dir, "textlike", lambda: Device(subs, mac(0x46), 0x8461, 0x8462),
                                     traffic)
    taken, other = "0x8461/0x8462=duplex:2/4,a20@2", "0x8461/0x8462=duplex:2/a24@2[/2d,2c,h,a4,a20]"
    got = tshark.frames(without, ["mcmb2.layout_entry", "mcmb2.layout_order", "mcmb2.candidate_setting"],
                        two_pass=True)
    assert {tuple(r.values()) for r in got.values()} == {(
        taken,
        "which downlink modules are ASCII taken from the frame order (SP-14-023 5.3: data modules first), though "
        "a data module holds text; with the text taken for ASCII (against the frame order) the layout is " + other,
        "mcmb2.layouts:" + other)}
    # the same with -Y (the sparse display builds only what the filter uses)
    sparse = tshark.frames(without, ["mcmb2.candidate_setting"], display_filter="mcmb2.candidate_setting",
                           two_pass=True)
    assert len(sparse) == 200 and {r["mcmb2.candidate_setting"] for r in sparse.values()} == {"mcmb2.layouts:" + other}
    note = tshark.frames(without, ["_ws.expert.message"], display_filter="mcmb2.layout.inferred", two_pass=True)
    assert [r["_ws.expert.message"] for r in note.values()] == [
        inferred_text(1, min(note), taken) + "; or, text as ASCII (against the frame order): " + other]
    fields = MCMB2_FIELDS + FIELDS
    a = tshark.frames(with_connect, fields, two_pass=True)
    assert a[4]["mcmb2.downlink_data"] == (b"PUMP" + b"CRANE HOIST NUMBER 1").hex()
    b = tshark.frames(without, fields, two_pass=True)
    assert all(row == a[n + 2] for n, row in b.items())
    for entry in (taken, other):
        pinned = tshark.frames(without, fields, prefs={"mcmb2.layouts": entry}, two_pass=True)
        assert all(row == a[n + 2] for n, row in pinned.items()), entry
