"""EG-Link (VM-110 UDP EG-Link, TS-0006) scenarios: captures/eglink_*.pcap.

A BU (192.168.32.10) and a machine controller (192.168.32.20) talk over the
multicast group 239.255.42.20 with TTL 1: the BU sends VRPI/VRCI/VRAI to the
input port 5825, the controller sends VRPO/VRCO/VRAO to the output port 5827.
Every packet is ID + 12-byte header + payload + CRC; the CRC is computed here
bit by bit, independently of the dissector.
"""
import struct

from .frames import udp_frame
from .pcap import Capture
from .registry import capture

MCAST = "239.255.42.20"
BU_IP, BU_MAC = "192.168.32.10", "00:30:11:20:00:10"
CTRL_IP, CTRL_MAC = "192.168.32.20", "00:1b:1b:20:00:20"
INPUT_PORT = 5825
OUTPUT_PORT = INPUT_PORT + 2
BU_ORIGIN = 0x1001
ARMED_RU = 0xBEEF

# BU states, link states, RU states (TS-0006 4.1.1 - 4.1.3)
INITIAL, STOPPED, EXT_LINK_ERROR, BLOCKED, FAILED, DISARMED, ARMED = 0x00, 0x01, 0x02, 0x03, 0x04, 0x10, 0x11
UNUSED, OPERATIONAL, NO_LINK, LINK_ERROR, INTERFACE_ERROR, DATA_ERROR, PASSIVE = range(7)
RU_INITIAL, RU_DISARMED, RU_ARMED, RU_ENABLED, RU_STOPPED = range(5)


# --- CRC-32 variants, bit by bit ---------------------------------------------

def crc32_mpeg2(data, crc=0xFFFFFFFF):
    """CRC-32/MPEG-2: poly 0x04C11DB7, init 0xFFFFFFFF, not reflected, no final XOR."""
    for byte in data:
        crc ^= byte << 24
        for _ in range(8):
            crc = ((crc << 1) ^ 0x04C11DB7) if crc & 0x80000000 else (crc << 1)
            crc &= 0xFFFFFFFF
    return crc


def crc32_bzip2(data):
    """CRC-32/BZIP2: CRC-32/MPEG-2 with a final XOR of 0xFFFFFFFF."""
    return crc32_mpeg2(data) ^ 0xFFFFFFFF


def crc32_iso_hdlc(data):
    """CRC-32/ISO-HDLC (Ethernet, zlib): reflected 0x04C11DB7, init and final XOR 0xFFFFFFFF."""
    crc = 0xFFFFFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xEDB88320 if crc & 1 else crc >> 1
    return crc ^ 0xFFFFFFFF


def crc32_stm32(data):
    """STM32 CRC unit fed little-endian 32-bit words (last word zero-padded)."""
    data = bytes(data) + bytes(-len(data) % 4)
    swapped = b"".join(data[i:i + 4][::-1] for i in range(0, len(data), 4))
    return crc32_mpeg2(swapped)


CRC = {"mpeg2": crc32_mpeg2, "bzip2": crc32_bzip2, "iso_hdlc": crc32_iso_hdlc, "stm32": crc32_stm32}

assert crc32_mpeg2(b"123456789") == 0x0376E6E7
assert crc32_bzip2(b"123456789") == 0xFC891918
assert crc32_iso_hdlc(b"123456789") == 0xCBF43926


# --- packets -------------------------------------------------------------------

def packet(ptype, payload, origin=0, serial=0, revision=0, size=None, spare=0,
           crc="mpeg2", crc_order="le", crc_value=None):
    """One EG-Link packet: ID, header, payload, CRC (variant, byte order or a fixed value)."""
    body = (ptype.encode("ascii") + struct.pack("<HHHHI", revision, origin, serial,
                                                len(payload) if size is None else size, spare)
            + bytes(payload))
    value = CRC[crc](body) if crc_value is None else crc_value
    return body + struct.pack("<I" if crc_order == "le" else ">I", value)


def vrpi(bu_state=ARMED, vlaps=1, unarmed_rus=0, eg_link=OPERATIONAL, ec_link=UNUSED,
         c_link=OPERATIONAL, armed_ru=0, ru_state=RU_INITIAL, battery=0, rssi=0, cable=0,
         docked=0, disabled=0, joysticks=(0, 0, 0, 0), switches=(0,) * 8, encoder=0,
         encoder_switch=0, spare=bytes(6)):
    """VRPI payload (46 bytes)."""
    return (struct.pack("<6BH6B", bu_state, vlaps, unarmed_rus, eg_link, ec_link, c_link, armed_ru,
                        ru_state, battery, rssi, cable, docked, disabled)
            + struct.pack("<4h", *joysticks) + struct.pack("<8h", *switches)
            + struct.pack("<BB", encoder & 0xFF, encoder_switch) + bytes(spare))


def armed(ru_state=RU_ENABLED, **kw):
    """VRPI payload of an armed RU with typical link and battery values."""
    values = dict(bu_state=ARMED, armed_ru=ARMED_RU, ru_state=ru_state, battery=87, rssi=72)
    values.update(kw)
    return vrpi(**values)


def disarmed(unarmed_rus=1, **kw):
    return vrpi(bu_state=DISARMED, unarmed_rus=unarmed_rus, c_link=PASSIVE, **kw)


def vrpo(packet_number, data):
    return struct.pack("<H", packet_number) + bytes(data)


def command(command_id, data, spare=bytes(4)):
    """VRCI/VRCO payload: command ID, spare, 16 bytes of command data."""
    data = bytes(data)
    return struct.pack("<H", command_id) + bytes(spare) + data + bytes(16 - len(data))


def ack(command_id):
    return struct.pack("<H", command_id)


def machine_data(cycle, size=64):
    """Periodic data a crane controller shows on the RU: load, height, slew, status."""
    head = struct.pack("<HhHHI", 2350 + 5 * cycle, 1200 - 3 * cycle, (450 + cycle) % 3600,
                       0x0001, cycle)
    text = b"HOIST 1 OK      "
    filler = bytes((cycle + i) & 0xFF for i in range(size))
    return (head + text + filler)[:size]


class Link:
    """The BU and the machine controller of one EG-Link, each with its own serial."""

    def __init__(self, cap=None, input_port=INPUT_PORT, origin=BU_ORIGIN, bu_ip=BU_IP,
                 ctrl_ip=CTRL_IP):
        self.cap = cap if cap is not None else Capture()
        self.input_port = input_port
        self.origin = origin
        self.bu_ip, self.ctrl_ip = bu_ip, ctrl_ip
        self.bu_serial = 0
        self.ctrl_serial = 0
        self.ip_id = 0

    def _send(self, t, src_ip, src_mac, port, pkt, snap=None):
        self.ip_id += 1
        frame = udp_frame(src_ip, MCAST, port, port, pkt, src_mac=src_mac, ttl=1, ip_id=self.ip_id)
        if snap is not None:
            return self.cap.add(t, frame[:len(frame) - snap], orig_len=len(frame))
        return self.cap.add(t, frame)

    def raw_bu(self, t, pkt, snap=None):
        """A ready-made packet from the BU (snap: bytes cut off the end of the frame)."""
        return self._send(t, self.bu_ip, BU_MAC, self.input_port, pkt, snap)

    def raw_ctrl(self, t, pkt, snap=None):
        return self._send(t, self.ctrl_ip, CTRL_MAC, self.input_port + 2, pkt, snap)

    def bu(self, t, ptype, payload, snap=None, **kw):
        """VRPI/VRCI/VRAI from the BU, next serial."""
        kw.setdefault("origin", self.origin)
        pkt = packet(ptype, payload, serial=self.bu_serial, **kw)
        self.bu_serial = (self.bu_serial + 1) & 0xFFFF
        return self.raw_bu(t, pkt, snap)

    def ctrl(self, t, ptype, payload, snap=None, **kw):
        """VRPO/VRCO/VRAO from the machine controller, next serial."""
        pkt = packet(ptype, payload, serial=self.ctrl_serial, **kw)
        self.ctrl_serial = (self.ctrl_serial + 1) & 0xFFFF
        return self.raw_ctrl(t, pkt, snap)


def periodic(link, start, end, vrpi_payload, vrpo_payload, events=()):
    """VRPI every 125 ms and VRPO every 100 ms from start to end (seconds); events are
    (t, fn) called in time order with the others. vrpi_payload(t), vrpo_payload(cycle)."""
    plan = []
    k = 0
    while start + 0.125 * k < end:
        plan.append((start + 0.125 * k, 0, k))
        k += 1
    k = 0
    while start + 0.040 + 0.100 * k < end:
        plan.append((start + 0.040 + 0.100 * k, 1, k))
        k += 1
    for t, fn in events:
        plan.append((t, 2, fn))
    for t, kind, arg in sorted(plan, key=lambda p: (p[0], p[1])):
        if kind == 0:
            link.bu(t, "VRPI", vrpi_payload(t))
        elif kind == 1:
            link.ctrl(t, "VRPO", vrpo(0, vrpo_payload(arg)))
        else:
            arg(t)


# --- scenarios ---------------------------------------------------------------

def _ramp(t, t0, t1, target):
    """A joystick moved smoothly from 0 to target between t0 and t1, held, then released."""
    if t < t0:
        return 0
    if t < t1:
        return int(target * (t - t0) / (t1 - t0))
    if t < t1 + 0.6:
        return target
    return 0


@capture("eglink_armed.pcap", "armed crane session: VRPI every 125 ms, VRPO every 100 ms, "
         "an operator command (VRCI/VRAO) and a controller command (VRCO/VRAI)")
def armed_session():
    link = Link()

    def controls(t):
        j1 = _ramp(t, 0.25, 1.0, -1000)       # hoist down, full speed
        j2 = _ramp(t, 1.1, 1.6, 420)          # slew right, slowly
        s1 = 1 if 1.75 <= t < 2.0 else 0      # horn pushbutton
        return armed(joysticks=(j1, j2, 0, 0), switches=(s1, 0, -1, 650, 0, 0, 0, 0),
                     encoder=int(t * 8), encoder_switch=0)

    events = (
        (1.3125, lambda t: link.bu(t, "VRCI", command(5, b"\x01\x00LIGHTS ON"))),
        (1.3240, lambda t: link.ctrl(t, "VRAO", ack(5))),
        (2.2100, lambda t: link.ctrl(t, "VRCO", command(1, b"\x10\x00OVERLOAD 95%"))),
        (2.2415, lambda t: link.bu(t, "VRAI", ack(1))),
    )
    periodic(link, 0.0, 3.0, controls, machine_data, events)
    return link.cap


@capture("eglink_disarmed.pcap", "no RU armed: BU disarmed, 0, 1 then 2 unarmed RUs, "
         "C-Link passive; controller keeps sending VRPO")
def disarmed_session():
    link = Link()
    periodic(link, 0.0, 1.5, lambda t: disarmed(unarmed_rus=min(2, int(t / 0.5))),
             machine_data)
    return link.cap


@capture("eglink_states.pcap", "every BU state, RU state, link status, RU disabled reason, "
         "cable/docked/encoder switch value, one VRPI each")
def all_states():
    link = Link()
    t = 0.0
    payloads = [
        vrpi(bu_state=INITIAL, eg_link=NO_LINK, ec_link=UNUSED, c_link=NO_LINK),
        armed(bu_state=STOPPED, ru_state=RU_STOPPED),
        vrpi(bu_state=EXT_LINK_ERROR, eg_link=LINK_ERROR, ec_link=INTERFACE_ERROR, c_link=DATA_ERROR),
        vrpi(bu_state=BLOCKED),
        vrpi(bu_state=FAILED),
        disarmed(unarmed_rus=3),
        armed(ru_state=RU_INITIAL),
        armed(ru_state=RU_DISARMED),
        armed(ru_state=RU_ARMED, disabled=1),
        armed(ru_state=RU_ARMED, disabled=2),
        armed(ru_state=RU_ARMED, disabled=3),
        armed(ru_state=RU_ENABLED, cable=1, docked=1, encoder_switch=1, vlaps=3),
        armed(ru_state=RU_ENABLED, vlaps=0, eg_link=PASSIVE,
              joysticks=(1000, -1000, 1, -1), switches=(1, -1, 1000, 3, 2, 0, -1, 1), encoder=255),
    ]
    for payload in payloads:
        link.bu(t, "VRPI", payload)
        t += 0.125
    return link.cap


@capture("eglink_commands.pcap", "VRCI retransmitted every 100 ms with the same Command ID "
         "and new serials until VRAO; VRCO retransmitted until VRAI")
def command_retransmission():
    link = Link()
    cmd = b"\x02\x00START PUMP"
    events = (
        (0.2000, lambda t: link.bu(t, "VRCI", command(7, cmd))),
        (0.3000, lambda t: link.bu(t, "VRCI", command(7, cmd))),
        (0.4000, lambda t: link.bu(t, "VRCI", command(7, cmd))),
        (0.4080, lambda t: link.ctrl(t, "VRAO", ack(7))),
        (0.6000, lambda t: link.ctrl(t, "VRCO", command(3, b"\x20\x00WIND 14 M/S"))),
        (0.7000, lambda t: link.ctrl(t, "VRCO", command(3, b"\x20\x00WIND 14 M/S"))),
        (0.7120, lambda t: link.bu(t, "VRAI", ack(3))),
    )
    periodic(link, 0.0, 1.0, lambda t: armed(), machine_data, events)
    return link.cap


@capture("eglink_vrpo_split.pcap", "1200 bytes of periodic data split into VRPO packets "
         "0, 1, 2 (488 + 488 + 224 bytes), three bursts 100 ms apart")
def vrpo_split():
    link = Link()
    for burst in range(3):
        data = machine_data(burst, size=1200)
        t = 0.1 * burst
        for number, start in enumerate(range(0, len(data), 488)):
            link.ctrl(t + 0.0002 * number, "VRPO", vrpo(number, data[start:start + 488]))
    return link.cap


@capture("eglink_bad_crc.pcap", "one packet of each type with a CRC that matches no variant, "
         "then a good VRPI")
def bad_crc():
    link = Link()
    link.bu(0.000, "VRPI", armed(), crc_value=0xDEADBEEF)
    link.ctrl(0.010, "VRPO", vrpo(0, machine_data(0)), crc_value=0x00000000)
    link.bu(0.020, "VRCI", command(9, b"\x01"), crc_value=0x12345678)
    link.ctrl(0.030, "VRAO", ack(9), crc_value=0xFFFFFFFF)
    link.ctrl(0.040, "VRCO", command(4, b"\x02"), crc_value=0xCAFEF00D)
    link.bu(0.050, "VRAI", ack(4), crc_value=0x0BADC0DE)
    link.bu(0.125, "VRPI", armed())
    return link.cap


CRC_VARIANTS = [(v, o) for v in ("mpeg2", "bzip2", "iso_hdlc", "stm32") for o in ("le", "be")]


@capture("eglink_crc_variants.pcap", "the same VRPI, VRCI and VRAO with the CRC in every "
         "variant and byte order (MPEG-2 LE, MPEG-2 BE, BZIP2 LE, ...)")
def crc_variants():
    link = Link()
    t = 0.0
    for variant, order in CRC_VARIANTS:
        link.bu(t, "VRPI", armed(), crc=variant, crc_order=order)
        link.bu(t + 0.01, "VRCI", command(11, b"\x03\x00MODE"), crc=variant, crc_order=order)
        link.ctrl(t + 0.02, "VRAO", ack(11), crc=variant, crc_order=order)
        t += 0.125
    return link.cap


@capture("eglink_wrong_size.pcap", "header Size that disagrees with the UDP length, payloads "
         "of the wrong size for their type, packets shorter than 20 bytes")
def wrong_sizes():
    link = Link()
    full = armed(joysticks=(100, 200, 300, 400))
    link.bu(0.00, "VRPI", full, size=40)                        # 1 Size says 40, carries 46
    link.bu(0.01, "VRPI", full[:30])                            # 2 VRPI payload 30 (Size 30)
    link.bu(0.02, "VRPI", full + b"\x00\x00\x00\x00")           # 3 VRPI payload 50
    link.ctrl(0.03, "VRPO", b"\x00")                            # 4 VRPO payload 1
    link.ctrl(0.04, "VRPO", vrpo(0, machine_data(0, 498)))      # 5 VRPO payload 500
    link.bu(0.05, "VRCI", command(5, b"\x01")[:20])             # 6 VRCI payload 20
    link.ctrl(0.06, "VRCO", command(5, b"\x01") + b"\x00\x00")  # 7 VRCO payload 24
    link.bu(0.07, "VRAI", ack(5) + b"\x00\x00")                 # 8 VRAI payload 4
    link.ctrl(0.08, "VRAO", b"")                                # 9 VRAO payload 0
    link.raw_bu(0.09, packet("VRPI", full, BU_ORIGIN)[:18])     # 10 18 bytes: no room for a CRC
    link.raw_bu(0.10, b"VRPI\x00\x00\x01\x10")                  # 11 8 bytes: half a header
    link.raw_bu(0.11, b"VRP")                                   # 12 3 bytes
    link.ctrl(0.12, "VRPO", vrpo(0, b""), size=0)               # 13 Size 0, carries 2
    return link.cap


@capture("eglink_truncated.pcap", "frames cut short by the capture snap length, one of each "
         "packet type (the UDP length still says the full size)")
def truncated():
    link = Link()
    link.bu(0.00, "VRPI", armed(joysticks=(-500, 0, 0, 0)), snap=30)   # cut inside the payload
    link.ctrl(0.01, "VRPO", vrpo(0, machine_data(0)), snap=2)          # cut inside the CRC
    link.bu(0.02, "VRCI", command(8, b"\x01"), snap=15)
    link.ctrl(0.03, "VRCO", command(8, b"\x01"), snap=30)              # cut inside the header
    link.bu(0.04, "VRAI", ack(8), snap=4)                              # CRC missing
    link.ctrl(0.05, "VRAO", ack(8), snap=19)                           # cut inside the ID
    return link.cap


@capture("eglink_unknown_type.pcap", "IDs starting with VR that TS-0006 does not define, "
         "between valid packets on the EG-Link ports")
def unknown_types():
    link = Link()
    link.bu(0.000, "VRPI", armed())
    link.bu(0.010, "VRXI", b"\x01\x02\x03\x04\x05\x06")
    link.ctrl(0.020, "VRPX", vrpo(0, b"abc"), origin=0)
    link.bu(0.030, "VRSI", b"")
    link.bu(0.125, "VRPI", armed())
    return link.cap


@capture("eglink_heuristic.pcap", "EG-Link on UDP ports 6100/6102 (found by the heuristic), "
         "and UDP data on port 6200 that only looks similar")
def heuristic_ports():
    link = Link(input_port=6100)
    link.bu(0.000, "VRPI", armed(joysticks=(250, 0, 0, 0)))
    link.ctrl(0.040, "VRPO", vrpo(0, machine_data(0)))
    link.bu(0.050, "VRCI", command(2, b"\x04"))
    link.ctrl(0.060, "VRAO", ack(2))
    link.ctrl(0.070, "VRCO", command(6, b"\x05"))
    link.bu(0.080, "VRAI", ack(6))
    other = Link(link.cap, input_port=6200)
    other.raw_bu(0.100, b"VRPI is not EG-Link: just some text over UDP")  # Size inconsistent
    other.raw_bu(0.110, packet("VRQI", b"\x00\x01"))                      # no known type
    link.bu(0.125, "VRPI", armed(joysticks=(300, 0, 0, 0)))
    return link.cap


@capture("eglink_range.pcap", "VRPI values outside TS-0006: joysticks, battery, RSSI, VLAPs, "
         "flags, RU disabled, states, link status, spares, RU data while none is armed")
def range_violations():
    link = Link()
    cases = [
        armed(joysticks=(1001, -1001, 32767, -32768)),                # 1 joysticks
        armed(battery=101, rssi=255),                                 # 2 percentages
        armed(vlaps=4),                                               # 3
        armed(ru_state=RU_ARMED, disabled=4),                         # 4
        armed(cable=2, docked=3, encoder_switch=255),                 # 5 flags
        vrpi(bu_state=DISARMED, battery=50, joysticks=(0, 10, 0, 0),  # 6 data while unarmed
             switches=(0, 0, 0, 0, 0, 0, 0, 1), encoder=3),
        armed(spare=b"\x00\x00\x01\x00\x00\x00"),                     # 7 payload spare
        vrpi(bu_state=0x05),                                          # 8 undefined, below 0x10
        vrpi(bu_state=0x20),                                          # 9 undefined, above
        armed(eg_link=7, ec_link=200, c_link=9),                      # 10 link status
        armed(ru_state=5),                                            # 11 RU state
        vrpi(bu_state=DISARMED, ru_state=RU_STOPPED),                 # 12 stopped, unarmed
    ]
    for i, payload in enumerate(cases):
        link.bu(0.125 * i, "VRPI", payload)
    return link.cap


@capture("eglink_header.pcap", "header rule breaches: revision, origin in controller packets "
         "and 0 in BU packets, non-zero header and command spares")
def header_violations():
    link = Link()
    link.bu(0.00, "VRPI", armed(), revision=1)                                 # 1
    link.ctrl(0.01, "VRPO", vrpo(0, machine_data(0)), origin=0x1001)           # 2
    link.ctrl(0.02, "VRCO", command(1, b"\x01"), origin=0x0002)                # 3
    link.ctrl(0.03, "VRAO", ack(1), origin=0xFFFF)                             # 4
    link.bu(0.04, "VRPI", armed(), origin=0)                                   # 5
    link.bu(0.05, "VRAI", ack(1), origin=0)                                    # 6
    link.bu(0.06, "VRCI", command(2, b"\x01"), spare=0x00000100)              # 7
    link.bu(0.07, "VRCI", command(3, b"\x01", spare=b"\x00\xff\x00\x00"))     # 8
    link.ctrl(0.08, "VRCO", command(2, b"\x01", spare=b"\x01\x00\x00\x00"))   # 9
    link.bu(0.125, "VRPI", armed())                                            # 10 clean
    return link.cap
