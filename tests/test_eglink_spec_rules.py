"""The TS-0006 rules of the EG-Link analysis, in each mode the specification
allows and broken once: VRPO packet numbers (4.2), VRPO timing and split
bursts (5.1.2), command resends (5.1.3, 5.1.4) and Command IDs (4.3, 4.5),
other header revisions (5.1.5), link status Passive (4.1.2) and RU state
Disarmed (4.1.3).

Sessions are built in memory with the capture generator's EG-Link link
(tools/capgen/eglink.py) and read in one pass and with -2: every finding of
the analysis above chat level, with its exact message, by frame.
"""
import itertools

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from conftest import expert_infos
from eglink_testlib import dissector_experts, gen

CHAT = "2097152"
SETTINGS = settings(max_examples=6, deadline=None, database=None, derandomize=True, phases=[Phase.generate],
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
NAMES = itertools.count()
CMD = b"\x01\x00HORN"


def write(work_dir, link):
    path = work_dir / ("spec_%d.pcap" % next(NAMES))
    path.write_bytes(link.cap.to_bytes())
    path.chmod(0o644)
    return path


def findings(tshark, capture, passes=(False, True), **kw):
    """{frame: [(expert name, message)]} of eglink.analysis.* above chat level,
    the same in one pass and with -2 (checked)."""
    got = []
    for two_pass in passes:
        out = {}
        for frame, name, severity, _, message, _ in expert_infos(tshark.json(capture, two_pass=two_pass, **kw)):
            if name.startswith("eglink.analysis.") and severity != CHAT and \
                    name not in ("eglink.analysis.retransmission",):
                out.setdefault(frame, []).append((name, message))
        got.append(out)
    assert got[0] == got[-1]
    return got[0]


def bursts(link, numbers, sizes, start=0.05, period=0.1, spread=0.0002):
    """VRPO bursts of link's controller: numbers[k] the packet numbers of burst k,
    sizes the bytes of data of each packet. Returns the frames, burst by burst."""
    frames = []
    for k, nums in enumerate(numbers):
        t = start + period * k
        frames.append([link.ctrl(round(t + spread * i, 6), "VRPO", gen.vrpo(n, gen.machine_data(k + i, size=s)))
                       for i, (n, s) in enumerate(zip(nums, sizes))])
    return frames


# --- VRPO packet numbers (TS-0006 4.2) -------------------------------------------------------

MODES = {
    "from 0": lambda k, n: [i for i in range(n)],
    "from 1": lambda k, n: [1 + i for i in range(n)],
    "running counter": lambda k, n: [k * n + i for i in range(n)],
    "running counter from 1000": lambda k, n: [1000 + k * n + i for i in range(n)],
}


@pytest.mark.parametrize("mode", MODES)
def test_every_numbering_is_reassembled_without_findings(tshark, work_dir, mode):
    """TS-0006 4.2: the packet number "shall be incremented by one for each packet";
    4.2/5.1.2: all packets of a burst full but the last. Each numbering the words
    allow (each burst from 0, from 1, one running counter) reassembles 1200-byte
    bursts (488 + 488 + 224) with no finding, one pass and -2."""
    link = gen.Link()
    frames = bursts(link, [MODES[mode](k, 3) for k in range(4)], [488, 488, 224])
    cap = write(work_dir, link)
    assert findings(tshark, cap) == {}
    for two_pass in (False, True):
        got = tshark.frames(cap, ["eglink.reassembled.length"], two_pass=two_pass)
        assert [f for f, r in got.items() if r["eglink.reassembled.length"] == "1200"] == \
            [b[-1] for b in frames]


@pytest.mark.parametrize("mode", MODES)
def test_single_packet_vrpo_in_every_numbering(tshark, work_dir, mode):
    """TS-0006 4.2: a VRPO of one packet per interval, numbered by each rule: no finding
    (before: "burst incomplete (packet 0 missing)" on every VRPO not numbered 0)."""
    link = gen.Link()
    bursts(link, [MODES[mode](k, 1) for k in range(5)], [64])
    assert findings(tshark, write(work_dir, link)) == {}


@pytest.mark.parametrize("numbers,frame,message", [
    # running counter: 0 1 2 2 -> a repeat
    ([[0], [1], [2], [2]], 4, "VRPO packet number 2, 3 expected (a repeat)"),
    # running counter: 0 1 2 1 -> a step back
    ([[0], [1], [2], [1]], 4, "VRPO packet number 1, 3 expected (a step back)"),
    # running counter: 0 1 2 5, no serial lost -> a gap
    ([[0], [1], [2], [5]], 4, "VRPO packet number 5, 3 expected (a gap with no packet lost)"),
    # from 1: 1 1 1 0 -> a step back
    ([[1], [1], [1], [0]], 4, "VRPO packet number 0, 1 expected (a step back)"),
])
def test_numbering_broken(tshark, work_dir, numbers, frame, message):
    """TS-0006 4.2: only what breaks the numbering the controller shows is flagged, on
    the packet that breaks it."""
    link = gen.Link()
    bursts(link, numbers, [64])
    assert findings(tshark, write(work_dir, link)) == {
        frame: [("eglink.analysis.vrpo_number",
                 message + ": TS-0006 §4.2 increments it by one for each packet")]}


def test_numbering_gap_from_a_lost_packet_is_the_serial_gap(tshark, work_dir):
    """TS-0006 3.2/4.2: a running counter that skips because a VRPO was lost (its serial
    missing too) is loss, not a numbering break."""
    link = gen.Link()
    bursts(link, [[0], [1]], [64])
    link.ctrl_serial += 1
    bursts(link, [[3], [4]], [64], start=0.35)
    assert findings(tshark, write(work_dir, link)) == {
        3: [("eglink.analysis.serial_gap", "1 packet lost from this sender: serial 2 expected, 3 received")]}


def test_gap_inside_a_burst_numbered_from_0(tshark, work_dir):
    """TS-0006 4.2: bursts from 0; the third is numbered 0, 2 with nothing lost: the
    number breaks it, and the burst cannot be reassembled."""
    link = gen.Link()
    bursts(link, [[0, 1], [0, 1], [0, 2], [0, 1]], [488, 100])
    assert findings(tshark, write(work_dir, link)) == {
        6: [("eglink.analysis.vrpo_number",
             "VRPO packet number 2, 1 expected (a gap with no packet lost): TS-0006 §4.2 increments it "
             "by one for each packet"),
            ("eglink.analysis.burst_incomplete",
             "VRPO burst is incomplete (packet 1 missing): its periodic data cannot be reassembled")]}


# --- VRPO timing and bursts (TS-0006 5.1.2) -------------------------------------------------------

@pytest.mark.parametrize("period_ms,note", [(40, True), (50, False), (100, False), (200, False),
                                            (250, True)])
def test_vrpo_interval(tshark, work_dir, period_ms, note):
    """TS-0006 5.1.2: "Recommended interval is 50 - 200ms": a note on every VRPO
    outside, none at 50 and 200 ms."""
    link = gen.Link()
    frames = bursts(link, [[0]] * 4, [64], period=period_ms / 1000)
    msg = ("VRPO 0.%03d s after the previous one: TS-0006 §5.1.2 recommends a VRPO every 50 to 200 ms"
           % period_ms)
    want = {b[0]: [("eglink.analysis.vrpo_interval", msg)] for b in frames[1:]} if note else {}
    assert findings(tshark, write(work_dir, link)) == want


def test_vrpo_interval_of_split_bursts_is_between_their_first_packets(tshark, work_dir):
    """TS-0006 5.1.2: "This bursts of packets shall be sent at the interval specified
    for the VRPO packet": the 0.2 ms between packets of a burst is no interval."""
    link = gen.Link()
    bursts(link, [[0, 1, 2]] * 3, [488, 488, 10], period=0.2)
    assert findings(tshark, write(work_dir, link)) == {}


def test_vrpo_interval_beyond_the_gap_threshold_is_the_gap(tshark, work_dir):
    """TS-0006 5.1.2: past 2000 ms the BU flags an error: the gap error says it, no note."""
    link = gen.Link()
    bursts(link, [[0]] * 2, [64], period=2.5)
    assert [n for n, _ in findings(tshark, write(work_dir, link))[2]] == ["eglink.analysis.vrpo_gap"]


def test_burst_spread(tshark, work_dir):
    """TS-0006 5.1.2: "the packets that make up one bunch of data shall be sent without
    delay between them": 15 ms between two packets of a burst is noted, 10 ms is not."""
    link = gen.Link()
    bursts(link, [[0, 1]], [488, 100], spread=0.010)
    bursts(link, [[0, 1]], [488, 100], start=0.15, spread=0.015)
    assert findings(tshark, write(work_dir, link)) == {
        4: [("eglink.analysis.burst_spread",
             "VRPO packet 1 0.015 s after the packet before it in its burst (more than 10 ms): TS-0006 "
             "§5.1.2 sends the packets of a split VRPO without delay")]}
    assert findings(tshark, write(work_dir, link), prefs={"eglink.burst_spread_ms": 20}) == {}


@pytest.mark.parametrize("first", [0, 1])
def test_vrpo_not_full(tshark, work_dir, first):
    """TS-0006 4.2: "All packets shall be full, besides the last one": a burst whose
    first packet carries 300 bytes and goes on; said on the packet that shows it, naming
    the short one. Bursts from 0 and from 1."""
    link = gen.Link()
    frames = bursts(link, [[first, first + 1]] * 2, [488, 100])
    frames += bursts(link, [[first, first + 1]], [300, 100], start=0.25)
    assert findings(tshark, write(work_dir, link)) == {
        6: [("eglink.analysis.vrpo_not_full",
             "VRPO packet %d (frame 5) carried 300 bytes but its burst goes on with packet %d: TS-0006 §4.2: "
             "all packets of a burst but the last are full (488 bytes)" % (first, first + 1))]}


# --- commands (TS-0006 4.3, 4.5, 5.1.3, 5.1.4) -------------------------------------------------

def vrci(link, t, cid):
    return link.bu(round(t, 6), "VRCI", gen.command(cid, CMD))


def vrco(link, t, cid):
    return link.ctrl(round(t, 6), "VRCO", gen.command(cid, CMD))


def test_resent_every_100_ms_until_acknowledged(tshark, work_dir):
    """TS-0006 5.1.3: "The BU will resend the VRCI packet every 100 ms until an
    acknowledge (VRAO) is received"; 5.1.4 the same for VRCO/VRAI: no finding."""
    link = gen.Link()
    for i in range(4):
        vrci(link, 0.1 + 0.1 * i, 1)
    link.ctrl(0.45, "VRAO", gen.ack(1))
    for i in range(3):
        vrco(link, 0.6 + 0.1 * i, 1)
    link.bu(0.85, "VRAI", gen.ack(1))
    link.bu(1.0, "VRPI", gen.armed())
    assert findings(tshark, write(work_dir, link)) == {}


@pytest.mark.parametrize("what,send,ack", [("VRCI", vrci, "VRAO"), ("VRCO", vrco, "VRAI")])
def test_sent_once_never_resent(tshark, work_dir, what, send, ack):
    """TS-0006 5.1.3/5.1.4: a command sent once, unacknowledged past 100 ms + 20 ms and
    never resent: flagged once, on the first packet past that time (here its late ack)."""
    link = gen.Link()
    send(link, 0.1, 1)
    if what == "VRCI":
        link.ctrl(0.3, "VRAO", gen.ack(1))
    else:
        link.bu(0.3, "VRAI", gen.ack(1))
    section = "5.1.3" if what == "VRCI" else "5.1.4"
    assert findings(tshark, write(work_dir, link)) == {
        2: [("eglink.analysis.not_resent",
             "%s command 1 (frame 1) not resent for 0.200 s while unacknowledged: TS-0006 §%s resends "
             "it every 100 ms until a %s" % (what, section, ack))]}


def test_resend_interval_and_after_ack(tshark, work_dir):
    """TS-0006 5.1.3: resent every 100 ms (a resend after 50 ms is noted) and only until
    acknowledged (a resend after the VRAO is noted)."""
    link = gen.Link()
    vrci(link, 0.1, 1)
    vrci(link, 0.15, 1)
    link.ctrl(0.16, "VRAO", gen.ack(1))
    vrci(link, 0.25, 1)
    assert findings(tshark, write(work_dir, link)) == {
        2: [("eglink.analysis.resend_interval",
             "VRCI command 1 resent 0.050 s after its previous transmission (frame 1): TS-0006 §5.1.3 "
             "resends it every 100 ms (tolerance 20 ms)")],
        4: [("eglink.analysis.resent_after_ack",
             "VRCI command 1 resent after its VRAO (frame 3): TS-0006 §5.1.3 resends it only until "
             "acknowledged")]}


def test_resent_after_the_deadline(tshark, work_dir):
    """TS-0006 5.1.3: "If no acknowledge is received within 2000 ms" the command has failed:
    a resend 2.1 s after the first transmission is noted as one of a failed command (only
    5.1.4 has the sender stop: that is the VRCO's wording)."""
    link = gen.Link()
    for i in range(22):
        vrci(link, 0.1 + 0.1 * i, 1)
    cap = write(work_dir, link)
    late = ("eglink.analysis.resent_after_deadline",
            "VRCI command 1 resent 2.100 s after its first transmission (frame 1), past its "
            "2000 ms deadline: TS-0006 §5.1.3 has the command failed by then")
    # one pass: the failed command's warning on the first packet past its deadline, the resend
    assert findings(tshark, cap, passes=(False,)) == {
        22: [("eglink.analysis.vrci_unacked",
              "VRCI command 1 (frame 1) not acknowledged by a VRAO within 2000 ms: the BU reports "
              "to the RU application that the command failed"), late]}
    # -2: the warning on the command, the deadline note on the resend
    assert findings(tshark, cap, passes=(True,)) == {
        1: [("eglink.analysis.vrci_unacked",
             "VRCI command 1 not acknowledged by a VRAO within 2000 ms (deadline at frame 22): the BU "
             "reports to the RU application that the command failed")],
        22: [("eglink.analysis.vrci_deadline",
              "Deadline of VRCI command 1 (frame 1) passed with no VRAO (2000 ms)"), late]}


def test_vrco_resent_after_the_deadline(tshark, work_dir):
    """TS-0006 5.1.4: the machine controller "should detect this as an error and stop
    sending the command" at its timeout: a VRCO resent 2.1 s after its first
    transmission says so, citing 5.1.4 (not 5.1.3, which says nothing of stopping)."""
    link = gen.Link()
    for i in range(22):
        vrco(link, 0.1 + 0.1 * i, 1)
    cap = write(work_dir, link)
    for two_pass in (False, True):
        got = findings(tshark, cap, passes=(two_pass,))
        assert [m for m in got[22] if m[0] == "eglink.analysis.resent_after_deadline"] == [
            ("eglink.analysis.resent_after_deadline",
             "VRCO command 1 resent 2.100 s after its first transmission (frame 1), past its "
             "2000 ms deadline: TS-0006 §5.1.4 stops sending the command at the timeout")], two_pass


@pytest.mark.parametrize("ids,bad", [
    ([7, 8, 9], None),                  # the first command sets the count
    ([65534, 65535, 0, 1], None),       # wrap-around
    ([1, 2, 4], (3, "VRCO command ID 4 after 2, 3 expected: TS-0006 §4.5 numbers commands sequentially")),
    ([5, 5], (2, "VRCO command ID 5 after 5, 6 expected: TS-0006 §4.5 numbers commands sequentially")),
])
def test_command_ids_sequential(tshark, work_dir, ids, bad):
    """TS-0006 4.5: "The machine controller shall number all generated commands
    sequentially" (4.3 the same for the BU): each new command's ID is the previous + 1,
    65535 followed by 0. Each command acknowledged at once; the reused ID comes after
    its timeout (a new command)."""
    link = gen.Link()
    t = 0.1
    for cid in ids:
        vrco(link, t, cid)
        link.bu(t + 0.01, "VRAI", gen.ack(cid))
        t += 2.5 if ids == [5, 5] else 0.2
    want = {} if bad is None else {2 * bad[0] - 1: [("eglink.analysis.command_id_sequence", bad[1])]}
    assert findings(tshark, write(work_dir, link)) == want


def test_command_ids_per_sender(tshark, work_dir):
    """TS-0006 4.3/4.5: the BU and the controller number their own commands."""
    link = gen.Link()
    for i, (send, ack_from, ack) in enumerate([(vrci, "ctrl", "VRAO"), (vrco, "bu", "VRAI")] * 2):
        cid = 1 + i // 2
        send(link, 0.1 + 0.2 * i, cid)
        getattr(link, ack_from)(0.11 + 0.2 * i, ack, gen.ack(cid))
    assert findings(tshark, write(work_dir, link)) == {}


# --- header revision (TS-0006 3.2, 5.1.5) -------------------------------------------------------

def test_other_revision_kept_out_of_the_analysis(tshark, work_dir):
    """TS-0006 5.1.5: "unsupported/unexpected header values" are ignored: a VRCI of
    revision 1 is no command (no retransmission, no ack link), its serial is counted."""
    link = gen.Link()
    link.bu(0.1, "VRCI", gen.command(1, CMD), revision=1)
    link.bu(0.2, "VRCI", gen.command(1, CMD))
    link.ctrl(0.21, "VRAO", gen.ack(1))
    cap = write(work_dir, link)
    assert findings(tshark, cap) == {
        1: [("eglink.analysis.revision_ignored",
             "Revision 1: kept out of the analysis, as TS-0006 §5.1.5 has receivers ignore unsupported "
             "header values (its serial is counted)")]}
    got = tshark.frames(cap, ["eglink.analysis.retransmission_of", "eglink.analysis.ack_to",
                              "eglink.analysis.lost"], two_pass=True)
    assert got[2] == {"eglink.analysis.retransmission_of": "", "eglink.analysis.ack_to": "",
                      "eglink.analysis.lost": ""}
    assert got[3]["eglink.analysis.ack_to"] == "2"


# --- link status Passive, RU state Disarmed (TS-0006 4.1.2, 4.1.3) -------------------------------

@pytest.mark.parametrize("kw,want", [
    (dict(bu_state=gen.DISARMED, c_link=gen.PASSIVE), []),
    (dict(armed_ru=0xBEEF, ru_state=3, c_link=gen.PASSIVE),
     [("eglink.link_status.passive",
       "C-Link status Passive while RU 0xbeef is armed: Passive only when no remote is armed")]),
    (dict(bu_state=gen.DISARMED, eg_link=gen.PASSIVE),
     [("eglink.link_status.passive", "EG-Link status Passive: only the C-Link reports Passive")]),
    (dict(bu_state=gen.DISARMED, ec_link=gen.PASSIVE),
     [("eglink.link_status.passive", "EC-Link status Passive: only the C-Link reports Passive")]),
    (dict(armed_ru=0xBEEF, ru_state=1),
     [("eglink.ru_state.disarmed", "RU state 1 (Disarmed) on the wire: TS-0006 uses it only inside the BU")]),
])
def test_passive_and_disarmed(tshark, work_dir, kw, want):
    """TS-0006 4.1.2: Passive "Can only be reported on C-Link when no remote is armed";
    4.1.3: RU state 1 Disarmed is "Only used internally". Same wording as eclink.*."""
    link = gen.Link()
    link.bu(0.0, "VRPI", gen.vrpi(**kw))
    got = dissector_experts(tshark, write(work_dir, link))
    assert got.get(1, []) == want


# --- properties: random timings around each limit ---------------------------------------------------

@SETTINGS
@given(st.lists(st.integers(60, 140), min_size=2, max_size=6))
def test_resend_intervals_property(tshark, work_dir, gaps_ms):
    """TS-0006 5.1.3: resends at random intervals around 100 ms: a resend_interval note
    exactly on the resends more than 20 ms from 100 ms; acknowledged 10 ms after the last."""
    link = gen.Link()
    t, frames, want = 0.1, [vrci(link, 0.1, 1)], {}
    for g in gaps_ms:
        t += g / 1000
        frames.append(vrci(link, t, 1))
        if abs(g - 100) > 20:
            want[frames[-1]] = [("eglink.analysis.resend_interval",
                                 "VRCI command 1 resent 0.%03d s after its previous transmission (frame %d): "
                                 "TS-0006 §5.1.3 resends it every 100 ms (tolerance 20 ms)" % (g, frames[-2]))]
    link.ctrl(round(t + 0.01, 6), "VRAO", gen.ack(1))
    # (a late resend is no "not resent": no other packet came before it)
    assert findings(tshark, write(work_dir, link)) == want


@SETTINGS
@given(st.lists(st.integers(30, 270), min_size=2, max_size=6))
def test_vrpo_intervals_property(tshark, work_dir, gaps_ms):
    """TS-0006 5.1.2: VRPO at random intervals around 50 and 200 ms (numbered from 1):
    a vrpo_interval note exactly on those outside 50..200 ms."""
    link = gen.Link()
    t, want = 0.05, {}
    link.ctrl(t, "VRPO", gen.vrpo(1, gen.machine_data(0)))
    for g in gaps_ms:
        t += g / 1000
        f = link.ctrl(round(t, 6), "VRPO", gen.vrpo(1, gen.machine_data(1)))
        if not 50 <= g <= 200:
            want[f] = [("eglink.analysis.vrpo_interval",
                        "VRPO 0.%03d s after the previous one: TS-0006 §5.1.2 recommends a VRPO every 50 "
                        "to 200 ms" % g)]
    assert findings(tshark, write(work_dir, link)) == want


@SETTINGS
@given(st.integers(90, 150), st.integers(0, 1))
def test_not_resent_property(tshark, work_dir, delay_ms, direction):
    """TS-0006 5.1.3/5.1.4: a command sent once, then a VRPI at a random time around
    100 ms + 20 ms: flagged not resent on that VRPI exactly when it comes later."""
    link = gen.Link()
    what, ack, section = (("VRCI", "VRAO", "5.1.3"), ("VRCO", "VRAI", "5.1.4"))[direction]
    (vrci, vrco)[direction](link, 0.1, 1)
    link.bu(round(0.1 + delay_ms / 1000, 6), "VRPI", gen.armed())
    want = {}
    if delay_ms > 120:
        want[2] = [("eglink.analysis.not_resent",
                    "%s command 1 (frame 1) not resent for 0.%03d s while unacknowledged: TS-0006 §%s resends "
                    "it every 100 ms until a %s" % (what, delay_ms, section, ack))]
    assert findings(tshark, write(work_dir, link)) == want


def test_command_ids_count_afresh_after_a_restart(tshark, work_dir):
    """TS-0006 4.5: a controller that restarted (its serial jumped back) numbers its
    commands afresh: VRCO 1 after VRCO 5 is no break then."""
    link = gen.Link()
    link.ctrl_serial = 5000
    vrco(link, 0.1, 5)
    link.bu(0.11, "VRAI", gen.ack(5))
    link.ctrl_serial = 0
    vrco(link, 0.3, 1)
    link.bu(0.31, "VRAI", gen.ack(1))
    assert findings(tshark, write(work_dir, link)) == {
        3: [("eglink.analysis.serial_restart", "Serial jumped back from 5000 to 0: the sender restarted?")]}


# --- a time just past its limit never reads as the limit ---------------------------------------

def _late_vrpo(link):
    link.ctrl(0.05, "VRPO", gen.vrpo(0, gen.machine_data(0)))
    return link.ctrl(0.2503, "VRPO", gen.vrpo(0, gen.machine_data(1)))


def _early_vrpo(link):
    link.ctrl(0.05, "VRPO", gen.vrpo(0, gen.machine_data(0)))
    return link.ctrl(0.0996, "VRPO", gen.vrpo(0, gen.machine_data(1)))


def _spread_burst(link):
    return bursts(link, [[0, 1]], [488, 100], spread=0.010004)[0][1]


def _resend_late(link):
    vrci(link, 0.1, 1)
    return vrci(link, 0.2204, 1)


def _resend_early(link):
    vrci(link, 0.1, 1)
    return vrci(link, 0.1796, 1)


def _not_resent(link):
    vrci(link, 0.1, 1)
    return link.bu(0.2203, "VRPI", gen.armed())


def _vrpi_gap(link):
    link.bu(0.0, "VRPI", gen.armed())
    return link.bu(0.500001, "VRPI", gen.armed())


@pytest.mark.parametrize("build,name,message", [
    (_late_vrpo, "eglink.analysis.vrpo_interval",
     "VRPO 0.2003 s after the previous one: TS-0006 §5.1.2 recommends a VRPO every 50 to 200 ms"),
    (_early_vrpo, "eglink.analysis.vrpo_interval",
     "VRPO 0.0496 s after the previous one: TS-0006 §5.1.2 recommends a VRPO every 50 to 200 ms"),
    (_spread_burst, "eglink.analysis.burst_spread",
     "VRPO packet 1 0.010004 s after the packet before it in its burst (more than 10 ms): TS-0006 "
     "§5.1.2 sends the packets of a split VRPO without delay"),
    (_resend_late, "eglink.analysis.resend_interval",
     "VRCI command 1 resent 0.1204 s after its previous transmission (frame 1): TS-0006 §5.1.3 "
     "resends it every 100 ms (tolerance 20 ms)"),
    (_resend_early, "eglink.analysis.resend_interval",
     "VRCI command 1 resent 0.0796 s after its previous transmission (frame 1): TS-0006 §5.1.3 "
     "resends it every 100 ms (tolerance 20 ms)"),
    (_not_resent, "eglink.analysis.not_resent",
     "VRCI command 1 (frame 1) not resent for 0.1203 s while unacknowledged: TS-0006 §5.1.3 resends "
     "it every 100 ms until a VRAO"),
    (_vrpi_gap, "eglink.analysis.vrpi_gap",
     "No VRPI for 0.500001 s (more than 500 ms): the machine controller should have flagged an error"),
])
def test_time_past_its_limit_shows_the_digits_that_tell(tshark, work_dir, build, name, message):
    """A time a hair past the limit it is flagged against (0.2003 s, outside 50 to 200 ms)
    would read as the limit itself when rounded to the millisecond: it gets the digits
    that tell it apart, in the message and the Info tag."""
    link = gen.Link()
    frame = build(link)
    assert findings(tshark, write(work_dir, link))[frame] == [(name, message)]


def test_gap_tag_past_its_limit(tshark, work_dir):
    link = gen.Link()
    frame = _vrpi_gap(link)
    cap = write(work_dir, link)
    assert tshark.frame(cap, frame, ["_ws.col.Info"])["_ws.col.Info"] == \
        "VRPI BU=Armed RU 0xbeef=Enabled [gap 0.500001 s]"


def test_late_ack_past_its_limit(tshark, work_dir):
    link = gen.Link()
    vrco(link, 0.1, 1)
    link.bu(2.1004, "VRAI", gen.ack(1))
    assert ("eglink.analysis.late_ack",
            "Acknowledges VRCO command 1 2.0004 s after its first transmission, later than 2000 ms") \
        in findings(tshark, write(work_dir, link), passes=(True,))[2]
