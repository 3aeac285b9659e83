"""A minimal, deterministic classic-pcap writer (microsecond timestamps)."""
import struct

LINKTYPE_ETHERNET = 1
LINKTYPE_USER0 = 147

# 2026-01-01 00:00:00 UTC: every capture starts here unless it says otherwise.
EPOCH = 1767225600.0


class Capture:
    """Frames with timestamps, written as one pcap file."""

    def __init__(self, linktype=LINKTYPE_ETHERNET, snaplen=262144):
        self.linktype = linktype
        self.snaplen = snaplen
        self.records = []  # (timestamp in seconds, frame bytes, original length)

    def add(self, t, frame, orig_len=None):
        """Add a frame at t seconds after EPOCH; orig_len > len(frame) makes a snapped frame."""
        frame = bytes(frame)
        self.records.append((EPOCH + t, frame, orig_len if orig_len is not None else len(frame)))
        return len(self.records)  # the frame number Wireshark will show

    def __len__(self):
        return len(self.records)

    def to_bytes(self):
        out = [struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, self.snaplen, self.linktype)]
        for ts, frame, orig_len in self.records:
            usec_total = int(round(ts * 1_000_000))
            sec, usec = divmod(usec_total, 1_000_000)
            out.append(struct.pack("<IIII", sec, usec, len(frame), orig_len))
            out.append(frame)
        return b"".join(out)
