"""Modbus/TCP traffic for the detection tests: BUs and ordinary devices, many
connections in one capture (so one tshark run checks them all).

Each connection gets its own server address and client port and its own
time window, so the capture's time stamps keep increasing.
"""
import struct

from tools.capgen import eclink_modbus as mbgen
from tools.capgen.pcap import Capture

CADENCE = 0.125  # the BU makes a new input image (PCI + 1) every 125 ms


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
        mb = mbgen.ModbusClient(self.cap, client_port=40000 + stream % 20000, server_port=server_port,
                                server_ip=server_ip, client_ip="10.0.0.1", t=self.t)
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
                  server_port=502):
    """A BU whose input image holds `fields` (mbgen.input_image arguments but
    pci) and whose PCI moves every 125 ms (first change `phase` s after the
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
        pci = (pci0 + int((t - t0 + phase) / CADENCE)) & 0xFF
        image = mbgen.input_image(pci=pci, **fields)
        _, resp = read_input(mb, t, fc, image)
        reads.append((resp, t, pci))
        if write:
            mb.write_regs(t + 0.004, 0, mbgen.regs(mbgen.output_image(pco=i, cao=fields.get("cci", 0))))
    traffic.done(t + 0.01)
    return stream, reads
