"""EG-Link conversation analysis scenarios: captures/eglink_analysis_*.pcap.

One finding per capture, on the link of tools/capgen/eglink.py (BU origin
0x1001 and its machine controller on 239.255.42.20, input port 5825): gaps
in VRPI and VRPO, lost and repeated packets, command retransmissions,
acknowledgements and timeouts in both directions, split VRPO bursts
(reassembled, incomplete, with and without the periodic data size), two BUs
side by side, two BUs and their controllers on one group (joined by their
commands, and not: unpaired), a BU replaced at its address, a session with
BU state changes for the statistics, packets that arrive corrupted, a
controller packet on the wrong port and a clock stepping back.
"""
from .eglink import (CTRL_MAC, EXT_LINK_ERROR, INITIAL, INPUT_PORT, RU_STOPPED, STOPPED, Link, ack,
                     armed, command, disarmed, machine_data, packet, vrpi, vrpo)
from .frames import udp_frame
from .registry import capture

VRPI_PERIOD = 0.125
VRPO_PERIOD = 0.100
VRPO_PHASE = 0.040


class GroupLink(Link):
    """A Link whose BU uses another multicast group."""

    def __init__(self, group, **kw):
        super().__init__(**kw)
        self.group = group

    def _send(self, t, src_ip, src_mac, port, pkt, snap=None):
        self.ip_id += 1
        return self.cap.add(t, udp_frame(src_ip, self.group, port, port, pkt, src_mac=src_mac,
                                         ttl=1, ip_id=self.ip_id))


def timeline(link, start, end, vrpi_at=None, vrpo_at=None, events=(), vrpi_payload=None,
             vrpo_payload=None):
    """VRPI every 125 ms and VRPO every 100 ms (+40 ms) in [start, end), merged with
    events (t, fn(t)). vrpi_at/vrpo_at(t) -> False drops that periodic packet (a gap);
    vrpi_payload(t), vrpo_payload(k) give the payloads. vrpi_at/vrpo_at are called in time
    order, when the packet is due, so they may use up a serial (a lost packet)."""
    plan = []
    k = 0
    while start + VRPI_PERIOD * k < end - 1e-9:
        plan.append((round(start + VRPI_PERIOD * k, 6), 0, k))
        k += 1
    k = 0
    while start + VRPO_PHASE + VRPO_PERIOD * k < end - 1e-9:
        plan.append((round(start + VRPO_PHASE + VRPO_PERIOD * k, 6), 1, k))
        k += 1
    for t, fn in events:
        plan.append((t, 2, fn))
    for t, kind, arg in sorted(plan, key=lambda p: (p[0], p[1])):
        if kind == 0 and vrpi_at is not None and not vrpi_at(t):
            continue
        if kind == 1 and vrpo_at is not None and not vrpo_at(t):
            continue
        if kind == 0:
            link.bu(t, "VRPI", (vrpi_payload or (lambda _t: armed()))(t))
        elif kind == 1:
            link.ctrl(t, "VRPO", vrpo(0, (vrpo_payload or machine_data)(arg)))
        else:
            arg(t)


def play(plan):
    """Runs the events (t, fn(t)) of a plan in time order."""
    for t, fn in sorted(plan, key=lambda p: p[0]):
        fn(round(t, 6))


def lose(link, serial, times):
    """A vrpi_at/vrpo_at predicate: the packets due at these times are sent (their
    serials used up: link.bu_serial or link.ctrl_serial) but not captured."""
    def keep(t):
        if t in times:
            setattr(link, serial, getattr(link, serial) + 1)
            return False
        return True
    return keep


@capture("eglink_analysis_vrpi_gap.pcap", "the BU's VRPI stop for 875 ms (VRPO go on): "
         "VRPI missing on the first VRPO after 500 ms, VRPI gap on the VRPI that ends it")
def vrpi_gap():
    link = Link()
    timeline(link, 0.0, 2.0, vrpi_at=lambda t: not 0.5 < t < 1.375)
    return link.cap


@capture("eglink_analysis_vrpo_gap.pcap", "armed crane, the machine controller stalls for "
         "2.5 s: the BU reports External link error (relays open), VRPO gap when it resumes, "
         "BU re-armed")
def vrpo_gap():
    link = Link()

    def state(t):
        if 3.0 <= t < 3.75:         # no VRPO for 2 s: the BU flags the link, relays open
            return vrpi(bu_state=EXT_LINK_ERROR, armed_ru=0xBEEF, ru_state=3, battery=87,
                        rssi=72)
        return armed()
    timeline(link, 0.0, 4.5, vrpo_at=lambda t: not 1.0 < t < 3.5, vrpi_payload=state)
    return link.cap


@capture("eglink_analysis_lost.pcap", "serial gaps: 2 VRPI lost (serials skipped), later "
         "1 VRPO lost")
def lost_packets():
    link = Link()
    timeline(link, 0.0, 1.2, vrpi_at=lose(link, "bu_serial", (0.5, 0.625)),
             vrpo_at=lose(link, "ctrl_serial", (0.84,)))
    return link.cap


@capture("eglink_analysis_repeated.pcap", "a VRPI captured twice (same serial) and an old "
         "VRPO serial replayed")
def repeated_packets():
    link = Link()

    def dup_vrpi(t):
        link.bu_serial -= 1     # the same packet again
        return link.bu(t, "VRPI", armed())

    def old_vrpo(t):
        serial = link.ctrl_serial
        link.ctrl_serial -= 3
        n = link.ctrl(t, "VRPO", vrpo(0, machine_data(99)))
        link.ctrl_serial = serial
        return n
    timeline(link, 0.0, 1.0, events=((0.3751, dup_vrpi), (0.7, old_vrpo)))
    return link.cap


CMD = b"\x02\x00START PUMP"


@capture("eglink_analysis_vrci_retransmission.pcap", "VRCI command 7 sent 3 times every "
         "100 ms (new serials, same Command ID), then VRAO after 230 ms")
def vrci_retransmission():
    link = Link()
    events = [(0.3 + 0.1 * i, lambda t: link.bu(t, "VRCI", command(7, CMD))) for i in range(3)]
    events.append((0.53, lambda t: link.ctrl(t, "VRAO", ack(7))))
    timeline(link, 0.0, 1.0, events=events)
    return link.cap


@capture("eglink_analysis_vrci_unacked.pcap", "VRCI command 8 retransmitted every 100 ms for "
         "1.9 s and never acknowledged: the BU gives up after 2000 ms")
def vrci_unacked():
    link = Link()
    events = [(round(0.2 + 0.1 * i, 6), lambda t: link.bu(t, "VRCI", command(8, CMD)))
              for i in range(20)]
    timeline(link, 0.0, 2.6, events=events)
    return link.cap


@capture("eglink_analysis_vrco.pcap", "VRCO command 3 retransmitted once, then VRAI; "
         "a VRAO and a VRAI for commands not in the capture")
def vrco_acked():
    link = Link()
    msg = b"\x20\x00WIND 14 M/S"
    events = (
        (0.10, lambda t: link.ctrl(t, "VRAO", ack(40))),
        (0.30, lambda t: link.ctrl(t, "VRCO", command(3, msg))),
        (0.40, lambda t: link.ctrl(t, "VRCO", command(3, msg))),
        (0.415, lambda t: link.bu(t, "VRAI", ack(3))),
        (0.70, lambda t: link.bu(t, "VRAI", ack(2))),
    )
    timeline(link, 0.0, 1.0, events=events)
    return link.cap


@capture("eglink_analysis_vrco_unacked.pcap", "VRCO command 4 never acknowledged; VRCO "
         "command 5 acknowledged by VRAI after 2.3 s (late); each resent every 100 ms for "
         "1.9 s, until its 2000 ms timeout (TS-0006 5.1.4)")
def vrco_unacked():
    link = Link()
    events = [(round(0.2 + 0.1 * i, 6), lambda t: link.ctrl(t, "VRCO", command(4, b"\x21\x00ALARM")))
              for i in range(20)]
    events += [(round(2.5 + 0.1 * i, 6), lambda t: link.ctrl(t, "VRCO", command(5, b"\x22\x00RESET")))
               for i in range(20)]
    events += [
        (4.8, lambda t: link.bu(t, "VRAI", ack(5))),
    ]
    timeline(link, 0.0, 5.0, events=events)
    return link.cap


def burst(link, t, number_from, data, numbers=None, skip=()):
    """VRPO packets of one burst, 200 us apart: data split in 488-byte pieces;
    numbers in skip are lost (their serials used). Returns the frames."""
    frames = []
    pieces = [data[i:i + 488] for i in range(0, len(data), 488)]
    for k, piece in enumerate(pieces):
        number = number_from + k if numbers is None else numbers[k]
        if number in skip:
            link.ctrl_serial += 1
            continue
        frames.append(link.ctrl(t + 0.0002 * k, "VRPO", vrpo(number, piece)))
    return frames


@capture("eglink_analysis_vrpo_split.pcap", "two 1200-byte VRPO bursts (488 + 488 + 224 bytes) "
         "100 ms apart, reassembled on their short last packet")
def vrpo_split():
    link = Link()
    burst(link, 0.05, 0, machine_data(0, size=1200))
    burst(link, 0.15, 0, machine_data(1, size=1200))
    return link.cap


@capture("eglink_analysis_vrpo_size.pcap", "three 976-byte VRPO bursts (two full packets "
         "each): the end is known from the next packet 0, or from the periodic size preference")
def vrpo_size():
    link = Link()
    for k in range(3):
        burst(link, 0.05 + 0.1 * k, 0, machine_data(k, size=976))
    return link.cap


@capture("eglink_analysis_vrpo_incomplete.pcap", "1200-byte VRPO bursts: packet 1 lost, "
         "packet 0 lost, packet 2 lost (seen at the next packet 0), then a complete one")
def vrpo_incomplete():
    link = Link()
    burst(link, 0.05, 0, machine_data(0, size=1200), skip=(1,))
    burst(link, 0.15, 0, machine_data(1, size=1200), skip=(0,))
    burst(link, 0.25, 0, machine_data(2, size=1200), skip=(2,))
    burst(link, 0.35, 0, machine_data(3, size=1200))
    return link.cap


@capture("eglink_analysis_two_bus.pcap", "two BUs (origins 0x1001 on 239.255.42.20 and 0x1002 "
         "on 239.255.42.21), one controller: same Command IDs on both, a lost VRPI on the second")
def two_bus():
    a = Link()
    b = GroupLink("239.255.42.21", cap=a.cap, origin=0x1002, bu_ip="192.168.32.11")
    plan = []
    for k in range(8):
        t = 0.125 * k
        plan.append((t, lambda t: a.bu(t, "VRPI", armed())))
        if k == 4:
            plan.append((t + 0.01, lambda t: setattr(b, "bu_serial", b.bu_serial + 1)))
        else:
            plan.append((t + 0.01, lambda t: b.bu(t, "VRPI", disarmed())))
    for k in range(10):
        plan.append((0.04 + 0.1 * k, lambda t: a.ctrl(t, "VRPO", vrpo(0, machine_data(1)))))
        plan.append((0.05 + 0.1 * k, lambda t: b.ctrl(t, "VRPO", vrpo(0, machine_data(2)))))
    plan += [
        (0.30, lambda t: a.bu(t, "VRCI", command(1, b"\x01\x00A"))),
        (0.31, lambda t: b.bu(t, "VRCI", command(1, b"\x01\x00B"))),
        (0.33, lambda t: b.ctrl(t, "VRAO", ack(1))),
        (0.36, lambda t: a.ctrl(t, "VRAO", ack(1))),
    ]
    play(plan)
    return a.cap


@capture("eglink_analysis_session.pcap", "BU start-up to armed operation: Initial, Disarmed, "
         "Armed, RU stop (Stopped), re-armed; commands both ways, one lost VRPI; for the "
         "statistics")
def session():
    link = Link()

    def state(t):
        if t < 0.5:
            return vrpi(bu_state=INITIAL)
        if t < 1.0:
            return disarmed()
        if 2.0 <= t < 2.5:
            return armed(bu_state=STOPPED, ru_state=RU_STOPPED)
        return armed()

    events = (
        (1.20, lambda t: link.bu(t, "VRCI", command(1, b"\x01\x00LIGHTS ON"))),
        (1.30, lambda t: link.bu(t, "VRCI", command(1, b"\x01\x00LIGHTS ON"))),
        (1.31, lambda t: link.ctrl(t, "VRAO", ack(1))),
        (1.70, lambda t: link.bu(t, "VRCI", command(2, b"\x01\x00HORN"))),
        (1.75, lambda t: link.ctrl(t, "VRAO", ack(2))),
        (2.20, lambda t: link.ctrl(t, "VRCO", command(9, b"\x10\x00OVERLOAD"))),
        (2.24, lambda t: link.bu(t, "VRAI", ack(9))),
    )
    timeline(link, 0.0, 3.0, vrpi_at=lose(link, "bu_serial", (1.5,)), events=events, vrpi_payload=state)
    return link.cap



class SharedLink(Link):
    """A BU and its controller at their own addresses, on the factory-default group and
    ports that every BU ships with (several of them share one group)."""

    def __init__(self, bu_ip, ctrl_ip, bu_mac, ctrl_mac, **kw):
        super().__init__(bu_ip=bu_ip, ctrl_ip=ctrl_ip, **kw)
        self.bu_mac, self.ctrl_mac = bu_mac, ctrl_mac

    def raw_bu(self, t, pkt, snap=None):
        return self._send(t, self.bu_ip, self.bu_mac, self.input_port, pkt, snap)

    def raw_ctrl(self, t, pkt, snap=None):
        return self._send(t, self.ctrl_ip, self.ctrl_mac, self.input_port + 2, pkt, snap)


def shared_pair(vrpis, vrpos):
    """Two BUs and their controllers on the default group (SharedLink): the
    links and the plan of their first vrpis VRPI and vrpos VRPO each."""
    a = SharedLink("10.0.0.1", "10.0.0.11", "00:30:11:20:01:01", "00:1b:1b:20:01:11")
    b = SharedLink("10.0.0.2", "10.0.0.12", "00:30:11:20:02:02", "00:1b:1b:20:02:12",
                   cap=a.cap, origin=0x2002)
    plan = []
    for k in range(vrpis):
        t = 0.125 * k
        plan.append((t, lambda t: a.bu(t, "VRPI", armed())))
        plan.append((t + 0.005, lambda t: b.bu(t, "VRPI", armed(armed_ru=0xCAFE))))
    for k in range(vrpos):
        plan.append((0.04 + 0.1 * k, lambda t, k=k: a.ctrl(t, "VRPO", vrpo(0, machine_data(k)))))
        plan.append((0.045 + 0.1 * k, lambda t, k=k: b.ctrl(t, "VRPO", vrpo(0, machine_data(50 + k)))))
    return a, b, plan


@capture("eglink_analysis_shared_group.pcap", "two armed BUs (10.0.0.1 origin 0x1001, 10.0.0.2 "
         "origin 0x2002) and their controllers (10.0.0.11, 10.0.0.12) on the default group "
         "239.255.42.20:5825/5827, nothing lost; commands both ways, the same Command IDs on "
         "both BUs once the controllers are joined")
def shared_group():
    a, b, plan = shared_pair(12, 15)
    plan += [
        # Each controller is joined to its BU by the first command it acknowledges ...
        (0.30, lambda t: a.bu(t, "VRCI", command(5, b"\x01\x00HORN"))),
        (0.32, lambda t: a.ctrl(t, "VRAO", ack(5))),
        (0.33, lambda t: b.bu(t, "VRCI", command(9, b"\x01\x00LIGHTS"))),
        (0.35, lambda t: b.ctrl(t, "VRAO", ack(9))),
        # ... then the same Command IDs on both BUs are kept apart.
        (0.60, lambda t: a.ctrl(t, "VRCO", command(2, b"\x10\x00LOAD A"))),
        (0.61, lambda t: b.ctrl(t, "VRCO", command(2, b"\x10\x00LOAD B"))),
        (0.62, lambda t: a.bu(t, "VRAI", ack(2))),
        (0.64, lambda t: b.bu(t, "VRAI", ack(2))),
        (0.90, lambda t: a.bu(t, "VRCI", command(6, b"\x01\x00STOP A"))),
        (0.91, lambda t: b.bu(t, "VRCI", command(10, b"\x01\x00STOP B"))),
        (0.93, lambda t: b.ctrl(t, "VRAO", ack(10))),
        (0.95, lambda t: a.ctrl(t, "VRAO", ack(6))),
    ]
    play(plan)
    return a.cap


@capture("eglink_analysis_origin_changed.pcap", "the BU at 192.168.32.10 is replaced: origin "
         "0x1001 until 0.5 s, then 0x1003 counting its serials from 0; one controller. Then "
         "a BU on 239.255.42.22 whose first VRPI has a bad CRC and a garbled origin 0xdead, "
         "then origin 0x1004: not an origin change")
def origin_changed():
    link = Link()

    def vrpi_at(t):
        if t >= 0.5 and link.origin == 0x1001:
            link.origin, link.bu_serial = 0x1003, 0
        return True
    timeline(link, 0.0, 1.0, vrpi_at=vrpi_at)
    other = GroupLink("239.255.42.22", cap=link.cap, origin=0x1004, bu_ip="192.168.32.12")
    other.bu(1.1, "VRPI", armed(), origin=0xDEAD, crc_value=0)
    for k in range(3):
        other.bu(1.225 + 0.125 * k, "VRPI", armed())
    return link.cap


@capture("eglink_analysis_corrupted.pcap", "VRPI every 125 ms from serial 100; the one with "
         "serial 103 (frame 8) arrives with a bad CRC, a VRPO (serial 6, frame 13) with a "
         "wrong Size: both are in the capture, so the next packet of each sender counts no loss")
def corrupted():
    link = Link()
    link.bu_serial = 100

    def vrpi_at(t):
        if t == 0.375:
            link.bu(t, "VRPI", armed(), crc_value=0)
            return False
        return True

    def vrpo_at(t):
        if t == 0.64:
            link.ctrl(t, "VRPO", vrpo(0, machine_data(6)), size=1)
            return False
        return True
    timeline(link, 0.0, 1.0, vrpi_at=vrpi_at, vrpo_at=vrpo_at)
    return link.cap


@capture("eglink_analysis_wrong_port.pcap", "a BU and its controller on 5825/5827; the BU's "
         "VRCI 5 is acknowledged by a VRAO the controller sends to port 6001 (frame 8), its VRCO "
         "7 sent to the input port 5825 (frame 14) is acknowledged: both belong to its "
         "conversation, on the wrong port")
def wrong_port():
    link = Link()

    def ctrl_to(port, ptype, payload):
        def send(t):
            pkt = packet(ptype, payload, serial=link.ctrl_serial)
            link.ctrl_serial += 1
            link._send(t, link.ctrl_ip, CTRL_MAC, port, pkt)
        return send
    events = (
        (0.30, lambda t: link.bu(t, "VRCI", command(5, b"\x01\x00HORN"))),
        (0.32, ctrl_to(6001, "VRAO", ack(5))),
        (0.60, ctrl_to(INPUT_PORT, "VRCO", command(7, b"\x10\x00LOAD"))),
        (0.62, lambda t: link.bu(t, "VRAI", ack(7))),
    )
    timeline(link, 0.0, 1.0, events=events)
    return link.cap


@capture("eglink_analysis_clock_step.pcap", "VRCO 4 at 0.2 s (resent every 100 ms until 0.9 s) "
         "is never acknowledged; at 1.0 s the capture's clock is set back 2 s (frame 27 reads "
         "-1.000 s): the step is a finding, no interval or age is below 0, and the command's "
         "deadline counts from the step (frame 64)")
def clock_step():
    link = Link()
    timeline(link, 0.0, 1.0, events=[(round(0.2 + 0.1 * i, 6),
                                      lambda t: link.ctrl(t, "VRCO", command(4, b"\x10\x00LOAD")))
                                     for i in range(8)])
    timeline(link, -1.0, 1.5)   # 1.0 s to 3.5 s on a clock 2 s behind
    return link.cap


@capture("eglink_analysis_unpaired.pcap", "two armed BUs (10.0.0.1 origin 0x1001, 10.0.0.2 "
         "origin 0x2002) on the default group, each with its own controller (10.0.0.11, "
         "10.0.0.12), no commands: 40 VRPI per BU, 40 VRPO per controller; the capture does not "
         "tell which controller serves which BU")
def unpaired():
    a, _, plan = shared_pair(40, 40)
    play(plan)
    return a.cap


def _split_bursts(link, start, count, late=None, short_first=None, gap_after=None, skip_one=None):
    """VRPO bursts of link's controller, numbered from 0: packet 0 full (488 bytes), packet 1
    of 100 bytes 200 us later, every 100 ms from start. late: the burst whose packet 1 comes
    15 ms after packet 0; short_first: the burst whose packet 0 carries 300 bytes; gap_after:
    the burst that comes 250 ms after the one before; skip_one: the burst numbered 0, 2."""
    plan, t = [], start
    for k in range(count):
        if k == gap_after:
            t += 0.150
        first = machine_data(k, size=300 if k == short_first else 488)
        second = (2 if k == skip_one else 1, machine_data(50 + k, size=100))
        plan.append((round(t, 6), lambda t, d=first: link.ctrl(t, "VRPO", vrpo(0, d))))
        plan.append((round(t + (0.015 if k == late else 0.0002), 6),
                     lambda t, n=second: link.ctrl(t, "VRPO", vrpo(n[0], n[1]))))
        t += 0.100
    return plan


@capture("eglink_analysis_spec_rules.pcap", "the rules of TS-0006 4.2, 4.3, 4.5, 5.1.2, 5.1.3 "
         "and 5.1.4 broken once each. BU 0x1001 (239.255.42.20): VRCI 1 resent after 100 and "
         "50 ms; VRCI 2 never resent, acknowledged after 200 ms; VRCI 3 resent after its VRAO; "
         "VRCO 1 then VRCO 3; VRCI 4 resent every 100 ms past its 2000 ms timeout. BU 0x1002 "
         "(239.255.42.21): split VRPO bursts numbered from 0, one spread out, one whose first "
         "packet is not full, one 250 ms after the one before, one numbered 0, 2")
def spec_rules():
    a = Link()
    b = GroupLink("239.255.42.21", cap=a.cap, origin=0x1002, bu_ip="192.168.32.11")
    cmd = b"\x01\x00HORN"
    plan = [(round(0.125 * k, 6), lambda t: a.bu(t, "VRPI", armed())) for k in range(33)]
    plan += [(round(0.04 + 0.1 * k, 6), lambda t, k=k: a.ctrl(t, "VRPO", vrpo(0, machine_data(k))))
             for k in range(40)]
    plan += [(round(0.005 + 0.125 * k, 6), lambda t: b.bu(t, "VRPI", armed())) for k in range(33)]
    plan += _split_bursts(b, 0.06, 38, late=3, short_first=5, gap_after=7, skip_one=10)
    plan += [
        (0.30, lambda t: a.bu(t, "VRCI", command(1, cmd))),
        (0.40, lambda t: a.bu(t, "VRCI", command(1, cmd))),
        (0.45, lambda t: a.bu(t, "VRCI", command(1, cmd))),         # 50 ms after the one before
        (0.46, lambda t: a.ctrl(t, "VRAO", ack(1))),
        (0.70, lambda t: a.bu(t, "VRCI", command(2, cmd))),         # never resent
        (0.90, lambda t: a.ctrl(t, "VRAO", ack(2))),
        (1.00, lambda t: a.bu(t, "VRCI", command(3, cmd))),
        (1.01, lambda t: a.ctrl(t, "VRAO", ack(3))),
        (1.10, lambda t: a.bu(t, "VRCI", command(3, cmd))),         # after its VRAO
        (1.20, lambda t: a.ctrl(t, "VRCO", command(1, b"\x10\x00LOAD"))),
        (1.21, lambda t: a.bu(t, "VRAI", ack(1))),
        (1.30, lambda t: a.ctrl(t, "VRCO", command(3, b"\x10\x00WIND"))),   # 2 expected
        (1.31, lambda t: a.bu(t, "VRAI", ack(3))),
    ]
    plan += [(round(1.5 + 0.1 * i, 6), lambda t: a.bu(t, "VRCI", command(4, cmd))) for i in range(22)]
    play(plan)
    return a.cap
