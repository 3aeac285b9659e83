"""Frame builders shared by the scenarios (Ethernet/IPv4/UDP/TCP, PROFINET RT).

scapy builds the headers and checksums; its output is deterministic for
explicitly given fields, which keeps the captures byte-identical.
"""
from scapy.layers.inet import IP, TCP, UDP
from scapy.layers.l2 import Dot1Q, Ether
from scapy.packet import Raw


def mcast_mac(ip):
    """The Ethernet multicast address of an IPv4 multicast group."""
    o = [int(x) for x in ip.split(".")]
    return "01:00:5e:%02x:%02x:%02x" % (o[1] & 0x7F, o[2], o[3])


def udp_frame(src_ip, dst_ip, sport, dport, payload, src_mac="00:30:11:00:00:01",
              dst_mac=None, ttl=1, ip_id=1):
    """Ethernet/IPv4/UDP; a multicast destination gets its multicast MAC."""
    if dst_mac is None:
        first = int(dst_ip.split(".")[0])
        dst_mac = mcast_mac(dst_ip) if 224 <= first <= 239 else "00:30:11:00:00:02"
    pkt = (Ether(src=src_mac, dst=dst_mac) / IP(src=src_ip, dst=dst_ip, ttl=ttl, id=ip_id)
           / UDP(sport=sport, dport=dport) / Raw(payload))
    return bytes(pkt)


def pn_rt_frame(src_mac, dst_mac, frame_id, c_sdu, cycle=0, data_status=0x35,
                transfer_status=0, vlan=None):
    """A PROFINET RT cyclic frame: FrameID, C-SDU, cycle counter, data/transfer status.

    vlan: None, or a VLAN ID (priority 6, as PROFINET RT uses).
    """
    body = frame_id.to_bytes(2, "big") + bytes(c_sdu)
    # The C-SDU of an RT_CLASS_1 frame is at least 40 bytes.
    if len(c_sdu) < 40:
        body += bytes(40 - len(c_sdu))
    body += (cycle & 0xFFFF).to_bytes(2, "big") + bytes([data_status, transfer_status])
    if vlan is None:
        pkt = Ether(src=src_mac, dst=dst_mac, type=0x8892) / Raw(body)
    else:
        pkt = Ether(src=src_mac, dst=dst_mac) / Dot1Q(prio=6, vlan=vlan, type=0x8892) / Raw(body)
    return bytes(pkt)


class TcpConnection:
    """One TCP connection with running sequence numbers.

    conn = TcpConnection(cap, "10.0.0.1", 50000, "10.0.0.2", 502)
    conn.handshake(t)               three-way handshake
    conn.client_send(t, data)       a segment from client to server (PSH/ACK)
    conn.server_send(t, data)
    Each returns the frame number in the capture.
    """

    def __init__(self, cap, client_ip, client_port, server_ip, server_port,
                 client_mac="00:1b:1b:00:00:01", server_mac="00:30:11:00:00:02",
                 client_isn=1000, server_isn=50000):
        self.cap = cap
        self.c = (client_ip, client_port, client_mac)
        self.s = (server_ip, server_port, server_mac)
        self.cseq = client_isn
        self.sseq = server_isn
        self.ip_id = 1

    def _frame(self, frm, to, seq, ack, flags, data=b""):
        self.ip_id = (self.ip_id + 1) & 0xFFFF
        pkt = (Ether(src=frm[2], dst=to[2]) / IP(src=frm[0], dst=to[0], id=self.ip_id, ttl=64)
               / TCP(sport=frm[1], dport=to[1], seq=seq, ack=ack, flags=flags, window=8192))
        if data:
            pkt = pkt / Raw(bytes(data))
        return bytes(pkt)

    def handshake(self, t):
        self.cap.add(t, self._frame(self.c, self.s, self.cseq, 0, "S"))
        self.cseq += 1
        self.cap.add(t + 0.0001, self._frame(self.s, self.c, self.sseq, self.cseq, "SA"))
        self.sseq += 1
        return self.cap.add(t + 0.0002, self._frame(self.c, self.s, self.cseq, self.sseq, "A"))

    def client_send(self, t, data):
        n = self.cap.add(t, self._frame(self.c, self.s, self.cseq, self.sseq, "PA", data))
        self.cseq += len(data)
        return n

    def server_send(self, t, data):
        n = self.cap.add(t, self._frame(self.s, self.c, self.sseq, self.cseq, "PA", data))
        self.sseq += len(data)
        return n
