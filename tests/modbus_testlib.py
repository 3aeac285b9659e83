"""Modbus/TCP traffic for the detection tests: BUs and ordinary devices, many
connections in one capture (so one tshark run checks them all).

Each connection gets its own server address and client port and its own
time window, so the capture's time stamps keep increasing.
"""
import socket
import struct

from tools.capgen import eclink_modbus as mbgen
from tools.capgen.frames import TcpConnection
from tools.capgen.pcap import Capture

CADENCE = 0.125  # the BU makes a new input image (PCI + 1) every 125 ms


TCP_FLAGS = {"F": 0x01, "S": 0x02, "R": 0x04, "P": 0x08, "A": 0x10}


def _checksum(data):
    if len(data) % 2:
        data += b"\0"
    total = sum(struct.unpack("!%dH" % (len(data) // 2), data))
    while total >> 16:
        total = (total & 0xFFFF) + (total >> 16)
    return ~total & 0xFFFF


class FastTcpConnection(TcpConnection):
    """capgen's TcpConnection with its frames packed by struct: the same
    Ethernet/IPv4/TCP headers, some hundred times faster than scapy (the
    property tests build hundreds of thousands of frames)."""

    def _frame(self, frm, to, seq, ack, flags, data=b""):
        self.ip_id = (self.ip_id + 1) & 0xFFFF
        src, dst = socket.inet_aton(frm[0]), socket.inet_aton(to[0])
        bits = sum(TCP_FLAGS[f] for f in flags)
        tcp = struct.pack("!HHIIBBHHH", frm[1], to[1], seq & 0xFFFFFFFF, ack & 0xFFFFFFFF, 5 << 4, bits,
                          8192, 0, 0) + bytes(data)
        csum = _checksum(src + dst + struct.pack("!BBH", 0, 6, len(tcp)) + tcp)
        tcp = tcp[:16] + struct.pack("!H", csum) + tcp[18:]
        ip = struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(tcp), self.ip_id, 0, 64, 6, 0, src, dst)
        ip = ip[:10] + struct.pack("!H", _checksum(ip)) + ip[12:]
        eth = bytes.fromhex(to[2].replace(":", "")) + bytes.fromhex(frm[2].replace(":", "")) + b"\x08\x00"
        return eth + ip + tcp


def modbus_client(cap, client_ip, client_port, server_ip, server_port, t):
    """capgen's ModbusClient over a FastTcpConnection (handshake at t)."""
    mb = mbgen.ModbusClient.__new__(mbgen.ModbusClient)
    mb.conn = FastTcpConnection(cap, client_ip, client_port, server_ip, server_port)
    mb.conn.handshake(t)
    mb.tid = 0
    mb.unit = 1
    return mb


class Traffic:
    """A capture of many Modbus/TCP connections, one after the other."""

    def __init__(self):
        self.cap = Capture()
        self.t = 0.0
        self.n = 0

    def client(self, server_port=502):
        """A new connection (handshake at self.t) to a new server; returns (ModbusClient, tcp.stream)."""
        stream = self.n
        self.n += 1
        server_ip = "10.%d.%d.%d" % (1 + stream // 65536, (stream // 256) % 256, stream % 256)
        mb = modbus_client(self.cap, "10.0.0.1", 40000 + stream % 20000, server_ip, server_port, self.t)
        return mb, stream

    def done(self, t_end):
        """The next connection starts after t_end."""
        self.t = max(self.t, t_end) + 0.5

    def write(self, folder, name):
        path = folder / name
        path.write_bytes(self.cap.to_bytes())
        path.chmod(0o644)
        return path


def read_input(mb, t, fc, image, dt=0.003):
    """The controller reads the whole input image (fc 4: input registers 0..31,
    fc 3: holding registers 2048..2079, fc 2: discrete inputs 0..511)."""
    if fc == 2:
        return mb.read_bits(t, 2, 0, 512, mbgen.bits(image, 0, 512))
    start = 0 if fc == 4 else 2048
    mb.tid = (mb.tid + 1) & 0xFFFF
    a = mb.conn.client_send(t, mb.adu(struct.pack(">BHH", fc, start, 32)))
    b = mb.conn.server_send(t + dt, mb.adu(struct.pack(">BB", fc, 64) + mbgen.regs(image)))
    return a, b


def bu_connection(traffic, fields, polls, poll, fc=4, write=False, phase=0.0, pci0=0, jitter=None,
                  server_port=502, period=CADENCE):
    """A BU whose input image holds `fields` (mbgen.input_image arguments but
    pci) and whose PCI moves every `period` s (first change `phase` s after the
    first read), read `polls` times every `poll` s; with write, the controller
    writes the 224-byte output image after each read.
    jitter: a list of offsets (s) added to each read's time.
    Returns (tcp.stream, [(read response frame, time, pci)])."""
    mb, stream = traffic.client(server_port)
    t0 = traffic.t + 0.01
    reads = []
    t = t0
    for i in range(polls):
        t = t0 + i * poll + (jitter[i] if jitter else 0.0)
        pci = (pci0 + int((t - t0 + phase) / period)) & 0xFF
        image = mbgen.input_image(pci=pci, **fields)
        _, resp = read_input(mb, t, fc, image)
        reads.append((resp, t, pci))
        if write:
            mb.write_regs(t + 0.004, 0, mbgen.regs(mbgen.output_image(pco=i, cao=fields.get("cci", 0))))
    traffic.done(t + 0.01)
    return stream, reads
