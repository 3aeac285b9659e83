"""EC-Link images over Modbus/TCP (TS-0007 chapter 5) and plain Modbus devices.

The BU is the Modbus/TCP server on port 502; the machine controller reads the
64-byte input image (input registers 0..31) and writes the output image
(holding registers 0..111). A register carries image byte 2n in its low 8 bits,
so on the wire each byte pair is swapped.
"""
import random
import struct

from .frames import TcpConnection
from .pcap import Capture
from .registry import capture

BU_IP = "192.168.2.41"
PLC_IP = "192.168.2.10"


def input_image(pci=0, cci=0, pai=0, cai=0, cmd=b"", bu_state=0x11, vlaps=1, unarmed=0,
                eg=1, ec=1, cl=1, armed_ru=0x1234, ru_state=3, battery=80, rssi=90, cable=0,
                docked=0, disabled=0, joy=(0, 0, 0, 0), sw=(0,) * 8, enc=0, encsw=0,
                spare=b"\0\0\0\0"):
    """The 64-byte input image (big-endian integers)."""
    img = bytes([pci & 0xFF, cci & 0xFF, pai & 0xFF, cai & 0xFF]) + bytes(cmd).ljust(16, b"\0")
    img += bytes([bu_state, vlaps, unarmed, eg, ec, cl]) + struct.pack(">H", armed_ru)
    img += bytes([ru_state, battery, rssi, cable, docked, disabled])
    img += struct.pack(">4h", *joy) + struct.pack(">8h", *sw) + bytes([enc, encsw]) + bytes(spare)
    assert len(img) == 64
    return img


def unarmed_image(**kw):
    """Input image of a disarmed BU: Armed RU 0 and every later field 0."""
    args = dict(bu_state=0x10, armed_ru=0, ru_state=0, battery=0, rssi=0, cl=6)
    args.update(kw)
    return input_image(**args)


def output_image(pco=0, cco=0, pao=0, cao=0, cmd=b"", size=0, block=0, spare=0, data=b"", std=True):
    """The output image: 224 bytes (Standard) or 20 bytes (Input + Commands)."""
    img = bytes([pco & 0xFF, cco & 0xFF, pao & 0xFF, cao & 0xFF]) + bytes(cmd).ljust(16, b"\0")
    if std:
        img += struct.pack(">HBB", size, block, spare) + bytes(data).ljust(200, b"\0")
    return img


def regs(image, swap=True):
    """Image bytes as register data on the wire (byte pairs swapped unless swap=False)."""
    out = bytearray(image)
    if swap:
        for i in range(0, len(out) - 1, 2):
            out[i], out[i + 1] = out[i + 1], out[i]
    return bytes(out)


def bits(image_bytes, start_bit, count):
    """count image bits from start_bit, packed LSB first as in a Modbus bit response."""
    out = bytearray((count + 7) // 8)
    for k in range(count):
        b = start_bit + k
        if image_bytes[b // 8] >> (b % 8) & 1:
            out[k // 8] |= 1 << (k % 8)
    return bytes(out)


class ModbusClient:
    """Modbus/TCP transactions over one TcpConnection (client = machine controller)."""

    def __init__(self, cap, client_port=50100, server_port=502, client_ip=PLC_IP, server_ip=BU_IP,
                 unit=1, t=0.0):
        self.conn = TcpConnection(cap, client_ip, client_port, server_ip, server_port)
        self.conn.handshake(t)
        self.tid = 0
        self.unit = unit

    def adu(self, pdu, tid=None):
        tid = self.tid if tid is None else tid
        return struct.pack(">HHHB", tid, 0, len(pdu) + 1, self.unit) + pdu

    def transact(self, t, req_pdu, resp_pdu, dt=0.003):
        """One request and its response; returns (request frame, response frame)."""
        self.tid = (self.tid + 1) & 0xFFFF
        a = self.conn.client_send(t, self.adu(req_pdu))
        b = self.conn.server_send(t + dt, self.adu(resp_pdu))
        return a, b

    def read_regs(self, t, fc, start, data):
        """fc 3 or 4: read len(data)/2 registers from start."""
        return self.transact(t, struct.pack(">BHH", fc, start, len(data) // 2),
                             struct.pack(">BB", fc, len(data)) + data)

    def read_bits(self, t, fc, start, count, packed):
        return self.transact(t, struct.pack(">BHH", fc, start, count),
                             struct.pack(">BB", fc, len(packed)) + packed)

    def write_regs(self, t, start, data):
        """fc 16."""
        n = len(data) // 2
        return self.transact(t, struct.pack(">BHHB", 16, start, n, len(data)) + data,
                             struct.pack(">BHH", 16, start, n))

    def write_reg(self, t, addr, value2):
        """fc 6: value2 = the 2 register bytes as on the wire."""
        pdu = struct.pack(">BH", 6, addr) + value2
        return self.transact(t, pdu, pdu)

    def write_coil(self, t, addr, on):
        pdu = struct.pack(">BHH", 5, addr, 0xFF00 if on else 0)
        return self.transact(t, pdu, pdu)

    def write_coils(self, t, start, count, packed):
        return self.transact(t, struct.pack(">BHHB", 15, start, count, len(packed)) + packed,
                             struct.pack(">BHH", 15, start, count))

    def read_write(self, t, rstart, rdata, wstart, wdata):
        """fc 23: write wdata at wstart, read len(rdata)/2 registers at rstart."""
        req = struct.pack(">BHHHHB", 23, rstart, len(rdata) // 2, wstart, len(wdata) // 2, len(wdata))
        return self.transact(t, req + wdata, struct.pack(">BB", 23, len(rdata)) + rdata)

    def exception(self, t, fc, req_pdu_tail, code):
        return self.transact(t, bytes([fc]) + req_pdu_tail, bytes([fc | 0x80, code]))


def cycle(mb, t, inp, out):
    """One controller cycle: read the input image, write the output image."""
    r = mb.read_regs(t, 4, 0, regs(inp))
    w = mb.write_regs(t + 0.010, 0, regs(out))
    return r + w


# The heuristic accepts a connection on a run of cycles only a BU and its
# controller give (lua/vrshark/modbus_detect.luam): PCI moving in the 125 ms
# cadence, output writes consistent over more than one write. A scenario
# too short for that ends with RUN_CYCLES such cycles (its frames are then
# decoded on the second pass, tshark -2), or starts with them (every frame
# of it decoded in one pass).
RUN_CYCLES = 3


def bu_run(mb, t, pci, pco, inp=None, out=None, n=RUN_CYCLES):
    """n healthy cycles 125 ms apart from time t, PCI and PCO counting on from
    pci and pco; inp and out: the other fields of the images (dicts).
    Returns the time after the run."""
    for k in range(n):
        cycle(mb, t + 0.125 * k, input_image(pci=pci + k, **(inp or {})), output_image(pco=pco + k, **(out or {})))
    return t + 0.125 * n


@capture("eclink_modbus_basic.pcap",
         "EC-Link over Modbus/TCP: cyclic input/output images, a command each way, BU Armed -> Blocked")
def basic():
    cap = Capture()
    mb = ModbusClient(cap)
    t = 0.1
    pci, cci, cai = 10, 3, 7
    pco, cco, cao = 20, 7, 3
    for i in range(12):
        t = 0.1 + i * 0.125
        pci += 1
        kw = {}
        if i == 3:
            cci = 4            # frame of cycle 3: a new command from RU
        if i == 5:
            cao = 4            # the controller echoes it 250 ms later
        if i == 6:
            cco = 8            # a command to RU
        if i == 8:
            cai = 8            # BU echoes it
        if i >= 10:
            kw = dict(bu_state=0x03, ru_state=0, joy=(0, 0, 0, 0))   # Blocked
        args = dict(pci=pci, cci=cci, cai=cai, cmd=b"CMD-FROM-RU-%02d" % cci,
                    joy=(500, -250, 0, 1000), sw=(1, 0, -1, 0, 0, 0, 0, 3), enc=42)
        args.update(kw)
        inp = input_image(**args)
        pco += 1
        out = output_image(pco=pco, cco=cco, cao=cao, cmd=b"CMD-TO-RU-%02d" % cco, size=120,
                           data=bytes(range(120)))
        cycle(mb, t, inp, out)
    return cap


@capture("eclink_modbus_functions.pcap",
         "EC-Link over Modbus/TCP: function codes 1, 2, 3, 4, 5, 6, 15, 16, 23, partial access, exception")
def functions():
    cap = Capture()
    mb = ModbusClient(cap)
    inp = input_image(pci=1, cci=2, cai=5, joy=(100, 200, -300, 0), sw=(1, -1, 0, 0, 0, 0, 0, 0))
    out = output_image(pco=1, cco=5, cao=2, size=0)
    t = 0.1
    mb.read_regs(t, 4, 0, regs(inp))                       # 4-5  fc 4 full input image (accepts)
    mb.read_regs(t + 0.1, 3, 2048, regs(inp))              # 6-7  fc 3 input image via 2048..2079
    mb.read_regs(t + 0.2, 4, 2, regs(inp[4:12]))           # 8-9  fc 4 regs 2..5 = bytes 4..11 (cut)
    mb.read_regs(t + 0.3, 3, 10, regs(out[20:24]))         # 10-11 fc 3 holding 10..11 = out 20..23
    mb.read_bits(t + 0.4, 2, 0, 512, bits(inp, 0, 512))    # 12-13 fc 2 all discrete inputs
    mb.read_bits(t + 0.5, 2, 163, 30, bits(inp, 163, 30))  # 14-15 fc 2 bits 163..192 (bytes 21..23 full)
    mb.read_bits(t + 0.6, 1, 0, 32, bits(out, 0, 32))      # 16-17 fc 1 coils 0..31 = out 0..3
    mb.write_coil(t + 0.7, 12, True)                       # 18-19 fc 5 coil 12 = out byte 1 bit 4
    mb.write_reg(t + 0.8, 1, regs(out[2:4]))               # 20-21 fc 6 reg 1 = out 2..3
    mb.write_coils(t + 0.9, 0, 16, bits(out, 0, 16))       # 22-23 fc 15 coils 0..15 = out 0..1
    mb.write_regs(t + 1.0, 0, regs(out))                   # 24-25 fc 16 full output image
    mb.read_write(t + 1.1, 0, regs(out[0:8]), 0, regs(out[0:20]))  # 26-27 fc 23 holding 0..3 / 0..9
    mb.exception(t + 1.2, 3, struct.pack(">HH", 200, 10), 2)       # 28-29 exception 0x83
    mb.read_regs(t + 1.3, 3, 2100, regs(bytes(8)))         # 30-31 outside the image map
    bu_run(mb, t + 1.4, 2, 2, dict(cci=2, cai=5, joy=(100, 200, -300, 0), sw=(1, -1, 0, 0, 0, 0, 0, 0)),
           dict(cco=5, cao=2))                             # 32-43 recognized in 41
    return cap


@capture("eclink_modbus_segments.pcap",
         "EC-Link over Modbus/TCP: two ADUs in one TCP segment, an ADU split over two segments")
def segments():
    cap = Capture()
    mb = ModbusClient(cap)
    c = mb.conn
    inp = input_image(pci=1)
    out = output_image(pco=1)
    mb.read_regs(0.1, 4, 0, regs(inp))                     # 4-5 accepts
    # two requests in one segment, two responses in one segment
    inp2 = input_image(pci=2, ru_state=2)
    r1 = mb.adu(struct.pack(">BHH", 4, 0, 32), tid=10)
    r2 = mb.adu(struct.pack(">BHHB", 16, 0, 10, 20) + regs(out[:20]), tid=11)
    c.client_send(0.2, r1 + r2)                            # 6
    a1 = mb.adu(struct.pack(">BB", 4, 64) + regs(inp2), tid=10)
    a2 = mb.adu(struct.pack(">BHH", 16, 0, 10), tid=11)
    c.server_send(0.203, a1 + a2)                          # 7
    # a response split over two segments
    inp3 = input_image(pci=3, ru_state=4)
    c.client_send(0.3, mb.adu(struct.pack(">BHH", 4, 0, 32), tid=12))   # 8
    a3 = mb.adu(struct.pack(">BB", 4, 64) + regs(inp3), tid=12)
    c.server_send(0.303, a3[:30])                          # 9
    c.server_send(0.304, a3[30:])                          # 10
    bu_run(mb, 0.425, 4, 2, dict(ru_state=4))               # 11-22 recognized in 20
    return cap


@capture("eclink_modbus_periodic.pcap",
         "EC-Link over Modbus/TCP: 450 bytes of periodic output data multiplexed in blocks 0..2")
def periodic():
    cap = Capture()
    mb = ModbusClient(cap)
    payload = bytes((i * 7 + 3) & 0xFF for i in range(450))
    pci = 0
    t = 0.1
    for rnd in range(2):
        for blk in range(3):
            pci += 1
            pco = rnd * 3 + blk + 1
            chunk = payload[blk * 200:(blk + 1) * 200]
            out = output_image(pco=pco, size=450, block=blk, data=chunk)
            cycle(mb, t, input_image(pci=pci, pai=pco - 1), out)
            t += 0.125
    # a block beyond the size
    pci += 1
    cycle(mb, t, input_image(pci=pci), output_image(pco=7, size=450, block=3))
    return cap


@capture("eclink_modbus_faults.pcap",
         "EC-Link over Modbus/TCP: PCI and PCO stalls, late and missing command echoes, bad values")
def faults():
    cap = Capture()
    mb = ModbusClient(cap)
    # 4-11: a healthy run the connection is recognized on (in 13)
    t = bu_run(mb, 0.1, 255, 255, dict(cci=1), dict(cao=1, cco=1), n=2)
    # 12-19: two good cycles; CCI changes in the second (new command from RU)
    cycle(mb, t, input_image(pci=1, cci=1), output_image(pco=1, cao=1, cco=1))
    cycle(mb, t + 0.125, input_image(pci=2, cci=2), output_image(pco=2, cao=1, cco=2))
    # 20-27: PCI stalls (same PCI 700 ms later), PCO keeps moving
    cycle(mb, t + 0.825, input_image(pci=2, cci=2), output_image(pco=3, cao=1, cco=2))
    cycle(mb, t + 0.95, input_image(pci=3, cci=2), output_image(pco=4, cao=1, cco=2))
    # 28-35: 2.6 s later: CAO still not echoing CCI 2, CCO 2 not echoed by CAI, PCO stalled
    cycle(mb, t + 3.0, input_image(pci=4, cci=2), output_image(pco=4, cao=1, cco=2))
    cycle(mb, t + 3.125, input_image(pci=5, cci=2), output_image(pco=5, cao=2, cco=2))
    # 36-39: bad values in the input image
    mb.read_regs(t + 3.25, 4, 0, regs(input_image(
        pci=6, cci=2, vlaps=4, eg=7, ru_state=5, battery=101, rssi=150, cable=2, docked=3,
        disabled=4, joy=(1001, -1001, 0, 0), encsw=2, spare=b"\0\1\0\0")))
    mb.read_regs(t + 3.3, 4, 0, regs(unarmed_image(pci=7, cci=2, bu_state=0x42, joy=(5, 0, 0, 0))))
    # 40-41: bad output image
    mb.write_regs(t + 3.35, 0, regs(output_image(pco=6, cao=2, cco=2, size=60000, block=1, spare=9)))
    return cap


@capture("eclink_modbus_link_states.pcap",
         "EC-Link over Modbus/TCP: values TS-0007 6.1.2/6.1.3 allow only in some states: C-Link Passive "
         "with an armed RU, EG-Link Passive, RU state 1 (Disarmed, internal); an EC-Link Data error while "
         "the BU stays Armed, RU state Enabled while RU disabled is tilted")
def link_states():
    cap = Capture()
    mb = ModbusClient(cap)
    # 4-15: a healthy run the connection is recognized on
    t = bu_run(mb, 0.1, 1, 1)
    # 16-19: C-Link Passive while RU 0x1234 is armed (the response: 17)
    cycle(mb, t, input_image(pci=4, cl=6), output_image(pco=4))
    # 20-23: RU state 1, Disarmed (21)
    cycle(mb, t + 0.125, input_image(pci=5, ru_state=1), output_image(pco=5))
    # 24-27: EG-Link Passive (25); 28-31: a disarmed BU with C-Link Passive, as allowed
    cycle(mb, t + 0.25, input_image(pci=6, eg=6), output_image(pco=6))
    cycle(mb, t + 0.375, unarmed_image(pci=7), output_image(pco=7))
    # 32-35: EC-Link Data error while the BU stays Armed (33, TS-0007 6.1.2, 9);
    # 36-39: RU state Enabled while RU disabled is 1, tilted (37, 6.1.3)
    cycle(mb, t + 0.5, input_image(pci=8, ec=5), output_image(pco=8))
    cycle(mb, t + 0.625, input_image(pci=9, disabled=1), output_image(pco=9))
    return cap


@capture("eclink_modbus_noswap.pcap",
         "EC-Link over Modbus/TCP from a device that puts image byte 2n in the HIGH register byte")
def noswap():
    cap = Capture()
    mb = ModbusClient(cap)
    inp = input_image(pci=9, armed_ru=0x0102, joy=(-1000, 1, 0, 0))
    mb.read_regs(0.1, 4, 0, regs(inp, swap=False))
    mb.write_regs(0.11, 0, regs(output_image(pco=5, size=300, block=1), swap=False))
    for k in range(RUN_CYCLES):                            # 8-19 recognized in 17
        cycle_regs = regs(input_image(pci=10 + k, armed_ru=0x0102, joy=(-1000, 1, 0, 0)), swap=False)
        mb.read_regs(0.225 + 0.125 * k, 4, 0, cycle_regs)
        mb.write_regs(0.235 + 0.125 * k, 0, regs(output_image(pco=6 + k, size=300, block=1), swap=False))
    return cap


@capture("eclink_modbus_port5020.pcap",
         "EC-Link over Modbus/TCP on port 5020 (needs Decode As)")
def port5020():
    cap = Capture()
    mb = ModbusClient(cap, server_port=5020)
    cycle(mb, 0.1, input_image(pci=1), output_image(pco=1))
    bu_run(mb, 0.225, 2, 2)                                # 8-19 recognized in 17
    return cap


@capture("eclink_modbus_late_accept.pcap",
         "EC-Link over Modbus/TCP: output writes before the first input image read, then a BU's run")
def late_accept():
    cap = Capture()
    mb = ModbusClient(cap)
    mb.write_regs(0.1, 0, regs(output_image(pco=1)))       # 4-5 before acceptance
    mb.read_regs(0.2, 4, 0, regs(input_image(pci=1)))      # 6-7 accepts in 7
    mb.write_regs(0.3, 0, regs(output_image(pco=2)))       # 8-9
    bu_run(mb, 0.325, 2, 3)                                # 10-21 recognized in 15
    return cap


@capture("modbus_plain_devices.pcap",
         "Ordinary Modbus/TCP devices (registers 0..111, 2048.., input registers): never EC-Link")
def plain_devices():
    cap = Capture()
    rnd = random.Random(7)
    # a device with arbitrary register values
    mb = ModbusClient(cap, client_port=50200, server_ip="192.168.2.50")
    t = 0.1
    for i in range(6):
        mb.read_regs(t, 4, 0, bytes(rnd.randrange(256) for _ in range(64)))
        mb.read_regs(t + 0.01, 3, 0, bytes(rnd.randrange(256) for _ in range(224)))
        mb.read_regs(t + 0.02, 3, 2048, bytes(rnd.randrange(256) for _ in range(64)))
        mb.write_regs(t + 0.03, 0, bytes(rnd.randrange(256) for _ in range(224)))
        mb.read_bits(t + 0.04, 2, 0, 512, bytes(rnd.randrange(256) for _ in range(64)))
        t += 0.1
    # a device of small values: counters and zeros (all links "Unused")
    mb2 = ModbusClient(cap, client_port=50201, server_ip="192.168.2.51", t=1.0)
    for i in range(6):
        data = bytearray(64)
        data[1] = i            # register 0 counts
        data[41] = 1           # register 20 = 1
        mb2.read_regs(1.1 + i * 0.1, 4, 0, bytes(data))
        mb2.read_regs(1.15 + i * 0.1, 3, 2048, bytes(data))
        mb2.write_regs(1.16 + i * 0.1, 0, bytes(224))
    # small values everywhere (0..6), but not a valid image
    mb3 = ModbusClient(cap, client_port=50202, server_ip="192.168.2.52", t=2.0)
    for i in range(4):
        mb3.read_regs(2.1 + i * 0.1, 4, 0, bytes(rnd.randrange(7) for _ in range(64)))
    return cap


def _midstream(cap, client_port, server_ip, client_isn=1000, server_isn=50000, tid=0):
    """A ModbusClient on a connection already open (an excerpt: no handshake)."""
    mb = ModbusClient.__new__(ModbusClient)
    mb.conn = TcpConnection(cap, PLC_IP, client_port, server_ip, 502, client_isn=client_isn,
                            server_isn=server_isn)
    mb.tid = tid
    mb.unit = 1
    return mb


def _io_flags(n):
    """An IO device's 0/1 digital inputs as its 32 input registers (on the
    wire): every value check of an input image passes, and nothing but 0/1."""
    values = [0] * 32
    values[10] = values[12] = values[13] = 1
    for k in (0, 5, 16):
        values[k] = (n // (3 + k % 2)) % 2
    return b"".join(struct.pack(">H", v) for v in values)


@capture("eclink_modbus_excerpt.pcap",
         "EC-Link over Modbus/TCP: a 17-frame excerpt (two input images and one write of a BU, too short "
         "for the evidence; an IO device polled like a BU beside it): eclink_modbus.servers decodes it")
def excerpt():
    cap = Capture()
    bu = _midstream(cap, 50100, BU_IP, client_isn=7000, server_isn=90000, tid=880)
    io = _midstream(cap, 50300, "192.168.2.60", client_isn=3000, server_isn=60000, tid=410)
    def counting(n):
        return b"".join(struct.pack(">H", n + k) for k in range(112))
    inp = dict(cci=6, cai=2, cmd=b"FROM-RU-COMMAND!", armed_ru=0x4242, battery=77, rssi=88,
               joy=(370, 0, 0, -12), enc=42)
    bu.read_regs(0.000, 4, 0, regs(input_image(pci=40, **inp)))              # 1-2 input image
    io.read_regs(0.010, 4, 0, _io_flags(0))                                  # 3-4 0/1 flags
    bu.write_regs(0.020, 0, regs(output_image(pco=7, cco=3, cao=6, cmd=b"TO-RU-COMMAND-16")))  # 5-6 write
    io.write_regs(0.030, 0, counting(0))                                      # 7-8 counting registers
    bu.read_regs(0.125, 4, 0, regs(input_image(pci=41, **inp)))              # 9-10 input image
    io.read_regs(0.135, 4, 0, _io_flags(1))                                  # 11-12
    io.write_regs(0.145, 0, counting(1))                        # 13-14
    bu.conn.client_send(0.250, bu.adu(struct.pack(">BHH", 4, 0, 32), tid=883))  # 15 cut after the request
    io.read_regs(0.260, 4, 0, _io_flags(2))                                  # 16-17
    return cap


def _mode_cycles(mb, outputs):
    """The BU in Input + Commands or Input Only mode (TS-0007 2.1, 5.1): 24
    cycles 125 ms apart (3 s); its RU sends a command (CCI 1 -> 2) at cycle
    6. outputs: the controller writes the 20-byte output image (holding
    registers 0..9), PCO never touched (0), CAO echoing CCI a cycle later;
    else it only reads."""
    cci = cao = 1
    for i in range(24):
        t = 0.1 + i * 0.125
        if i == 6 and outputs:         # (Input Only transfers no commands)
            cci = 2
        inp = input_image(pci=i + 1, cci=cci, cai=0, cmd=b"CMD-FROM-RU-%02d" % cci, joy=(i * 10, 0, 0, 0))
        if outputs:
            cycle(mb, t, inp, output_image(pco=0, cco=0, cao=cao, cmd=b"CMD-TO-RU", std=False))
            cao = cci
        else:
            mb.read_regs(t, 4, 0, regs(inp))


@capture("eclink_modbus_commands.pcap",
         "EC-Link over Modbus/TCP, Input + Commands mode: 20-byte output writes whose PCO never moves (3 s), "
         "a command from RU echoed by CAO; the mode noted, no PCO stall (TS-0007 2.1, 8.4)")
def commands_mode():
    cap = Capture()
    _mode_cycles(ModbusClient(cap), True)
    return cap


@capture("eclink_modbus_input_only.pcap",
         "EC-Link over Modbus/TCP, Input Only mode: the controller only reads the input image (3 s)")
def input_only_mode():
    cap = Capture()
    _mode_cycles(ModbusClient(cap), False)
    return cap


def _tcp_end(conn, t, flags, from_client):
    """A FIN ("FA": and the other side's FIN, then the last ACK) or RST ("RA")
    segment ending conn at t, from the controller or the BU."""
    a, b = (conn.c, conn.s) if from_client else (conn.s, conn.c)
    seq, ack = (conn.cseq, conn.sseq) if from_client else (conn.sseq, conn.cseq)
    conn.cap.add(t, conn._frame(a, b, seq, ack, flags))
    if flags == "FA":
        conn.cap.add(t + 0.0001, conn._frame(b, a, ack, seq + 1, "FA"))
        conn.cap.add(t + 0.0002, conn._frame(a, b, seq + 1, ack + 1, "A"))


@capture("eclink_modbus_stops.pcap",
         "EC-Link over Modbus/TCP: a BU's input image no longer read, then its output image no longer "
         "written and its connection closed (FIN); a second BU's connection reset (RST) and opened again; "
         "an ordinary server polled throughout")
def stops():
    """Every 125 ms (tick k at t = 0.1 + 0.125 k): BU 1's cycle at t, BU 2's
    at t + 0.03, the ordinary server's read (4 holding registers at 100) at
    t + 0.09. Each end is followed first by a frame of a BU's connection."""
    cap = Capture()
    # 1-3, 4-6, 7-9: the TCP handshakes of BU 1, BU 2 and the ordinary server
    bu1 = ModbusClient(cap)
    bu2 = ModbusClient(cap, client_port=50101, server_ip="192.168.2.42", t=0.01)
    other = ModbusClient(cap, client_port=50102, server_ip="192.168.2.50", t=0.02)
    pci = pco = 0
    for k in range(43):
        t = 0.1 + 0.125 * k
        if k < 6:
            # ticks 0-5: healthy (BU 1's last read of the input image at 0.725 s)
            cycle(bu1, t, input_image(pci=pci), output_image(pco=pco))
        elif k < 12:
            # ticks 6-11: BU 1's input image no longer read, its output image
            # written (the last time at 1.485 s)
            bu1.write_regs(t + 0.010, 0, regs(output_image(pco=pco)))
        if k == 37:
            # the controller connects to BU 2 again, 5 ms after the reset
            bu2 = ModbusClient(cap, client_port=50103, server_ip="192.168.2.42", t=t - 0.025)
        cycle(bu2, t + 0.03, input_image(pci=pci), output_image(pco=pco))
        other.read_regs(t + 0.090, 3, 100, bytes(range(k, k + 8)))
        if k == 12:
            # the controller closes BU 1's connection at 1.695 s (3 frames)
            _tcp_end(bu1.conn, t + 0.095, "FA", True)
        if k == 36:
            # BU 2 resets its connection at 4.695 s
            _tcp_end(bu2.conn, t + 0.095, "RA", False)
        pci, pco = (pci + 1) & 0xFF, (pco + 1) & 0xFF
    return cap
