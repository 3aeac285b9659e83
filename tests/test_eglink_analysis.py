"""EG-Link conversation analysis: per-BU serial and interval tracking, command
links and timeouts, VRPO reassembly, statistics; one pass and two passes agree.

Captures: tools/capgen/eglink_analysis.py. Every expert test lists ALL the
analysis expert infos of its capture, so it checks both where a finding must
appear and that it appears nowhere else.
"""
import re

import pytest


def analysis_experts(tshark, capture, **kw):
    """{frame: [(expert name, message)]} of the eglink.analysis.* expert infos."""
    out = {}

    def walk(node, frame):
        if isinstance(node, list):
            for item in node:
                walk(item, frame)
        elif isinstance(node, dict):
            for key, value in node.items():
                if key == "_ws.expert":
                    for e in value if isinstance(value, list) else [value]:
                        names = [k for k in e if not k.startswith("_ws.expert")]
                        if names and names[0].startswith("eglink.analysis."):
                            out.setdefault(frame, []).append((names[0], e["_ws.expert.message"]))
                else:
                    walk(value, frame)

    for pkt in tshark.json(capture, **kw):
        layers = pkt["_source"]["layers"]
        walk(layers.get("eglink", {}), int(layers["frame"]["frame.number"]))
    return out


def names(experts):
    """{frame: [expert names]}"""
    return {f: [n for n, _ in v] for f, v in experts.items()}


def cols(tshark, capture, fields, **kw):
    """{frame: (values of fields...)} for frames that have any of the fields."""
    rows = tshark.fields(capture, ["frame.number"] + fields, **kw)
    return {int(r[0]): tuple(r[1:]) for r in rows if any(r[1:])}


@pytest.fixture(scope="module")
def cap(capture_file):
    return lambda name: capture_file("eglink_analysis_%s.pcap" % name)


# --- periodic packets ---------------------------------------------------------

def test_vrpi_gap(tshark, cap):
    exp = analysis_experts(tshark, cap("vrpi_gap"))
    assert exp == {
        16: [("eglink.analysis.vrpi_missing",
              "No VRPI from this BU for 0.540 s (more than 500 ms, last in frame 10)")],
        20: [("eglink.analysis.vrpi_gap",
              "No VRPI for 0.875 s since frame 10 (more than 500 ms): the machine controller "
              "should have flagged an error")],
    }


def test_vrpi_intervals(tshark, cap):
    rows = cols(tshark, cap("vrpi_gap"), ["eglink.analysis.time_since_prev_vrpi"])
    assert rows[3] == ("0.125000000",)
    assert rows[20] == ("0.875000000",)
    assert set(v for f, v in rows.items() if f != 20) == {("0.125000000",)}
    assert 1 not in rows        # the first VRPI has no previous one


def test_vrpi_gap_threshold_preference(tshark, cap):
    """A threshold above the gap silences both findings; one below flags every VRPI."""
    assert analysis_experts(tshark, cap("vrpi_gap"), prefs={"eglink.vrpi_gap_ms": 900}) == {}
    exp = names(analysis_experts(tshark, cap("vrpi_gap"), prefs={"eglink.vrpi_gap_ms": 100}))
    vrpi = tshark.field(cap("vrpi_gap"), "frame.number", display_filter='eglink.type == "VRPI"')
    assert sorted(f for f, n in exp.items() if "eglink.analysis.vrpi_gap" in n) == \
        [int(f) for f in vrpi[1:]]


def test_vrpo_gap_relays_open(tshark, cap):
    exp = analysis_experts(tshark, cap("vrpo_gap"))
    assert exp == {
        35: [("eglink.analysis.vrpo_missing",
              "No VRPO to this BU for 2.060 s (more than 2000 ms, last in frame 18): the BU flags "
              "an error and, with an RU armed, opens the ES-Link relays"),
             ("eglink.analysis.bu_state_changed",
              "BU state changed from Armed (0x11) to External link error (0x02)")],
        40: [("eglink.analysis.vrpo_gap",
              "No VRPO for 2.600 s since frame 18 (more than 2000 ms): the BU flags an error "
              "and, with an RU armed, opens the ES-Link relays")],
        44: [("eglink.analysis.bu_state_changed",
              "BU state changed from External link error (0x02) to Armed (0x11)")],
    }
    rows = cols(tshark, cap("vrpo_gap"), ["eglink.analysis.time_since_prev_vrpo"])
    assert rows[40] == ("2.600000000",)
    assert rows[18] == ("0.100000000",)


def test_vrpo_gap_threshold_preference(tshark, cap):
    exp = names(analysis_experts(tshark, cap("vrpo_gap"), prefs={"eglink.vrpo_gap_ms": 3000}))
    assert exp == {35: ["eglink.analysis.bu_state_changed"],
                   44: ["eglink.analysis.bu_state_changed"]}


# --- serial numbers -----------------------------------------------------------

def test_lost_packets(tshark, cap):
    assert analysis_experts(tshark, cap("lost")) == {
        13: [("eglink.analysis.serial_gap",
              "2 packets lost from this sender: serial 4 expected, 6 received")],
        15: [("eglink.analysis.serial_gap",
              "1 packet lost from this sender: serial 8 expected, 9 received")],
    }
    rows = cols(tshark, cap("lost"), ["eglink.analysis.lost"])
    assert rows == {13: ("2",), 15: ("1",)}
    assert cols(tshark, cap("lost"), ["eglink.analysis.expected_serial"],
                display_filter="frame.number == 13") == {13: ("4",)}


def test_repeated_packets(tshark, cap):
    assert analysis_experts(tshark, cap("repeated")) == {
        9: [("eglink.analysis.serial_repeat",
             "Repeated packet: serial 3 was already received in frame 8; not analysed further")],
        15: [("eglink.analysis.serial_repeat",
              "Repeated or reordered packet: serial 4 is older than the last one received (6); "
              "not analysed further")],
    }
    assert cols(tshark, cap("repeated"), ["eglink.analysis.repeat_of"]) == {9: ("8",)}
    # The repeat is left out of the intervals: the next VRPI counts from frame 8.
    rows = cols(tshark, cap("repeated"), ["eglink.analysis.time_since_prev_vrpi"])
    assert 9 not in rows and rows[11] == ("0.125000000",)


# --- commands -------------------------------------------------------------------

def test_vrci_retransmission_then_ack(tshark, cap):
    assert analysis_experts(tshark, cap("vrci_retransmission")) == {
        10: [("eglink.analysis.retransmission",
              "Retransmission of VRCI command 7 (first sent in frame 7)")],
        13: [("eglink.analysis.retransmission",
              "Retransmission of VRCI command 7 (first sent in frame 7)")],
    }
    fields = ["eglink.analysis.retransmission_of", "eglink.analysis.ack_in",
              "eglink.analysis.ack_to", "eglink.analysis.ack_time"]
    assert cols(tshark, cap("vrci_retransmission"), fields, two_pass=True) == {
        7: ("", "14", "", ""),
        10: ("7", "14", "", ""),
        13: ("7", "14", "", ""),
        14: ("", "", "7", "0.230000000"),
    }
    # One pass cannot know the acknowledgement of an earlier frame yet.
    assert cols(tshark, cap("vrci_retransmission"), fields) == {
        10: ("7", "", "", ""),
        13: ("7", "", "", ""),
        14: ("", "", "7", "0.230000000"),
    }


def test_vrci_never_acknowledged(tshark, cap):
    exp = analysis_experts(tshark, cap("vrci_unacked"))
    retrans = {f for f, v in exp.items() if v == [("eglink.analysis.retransmission",
                                                  "Retransmission of VRCI command 8 (first sent in frame 5)")]}
    assert len(retrans) == 19
    failed = {f: v for f, v in exp.items() if f not in retrans}
    # The first packet of the BU later than 2000 ms after the first VRCI (t=0.2 s):
    # the VRPO at 2.24 s.
    assert failed == {61: [("eglink.analysis.vrci_unacked",
                            "VRCI command 8 (frame 5) not acknowledged by a VRAO within 2000 ms: "
                            "the BU reports to the RU application that the command failed")]}
    assert cols(tshark, cap("vrci_unacked"), ["eglink.analysis.failed_command"]) == {61: ("5",)}
    assert cols(tshark, cap("vrci_unacked"), ["eglink.analysis.ack_in"], two_pass=True) == {}


def test_vrci_timeout_preference(tshark, cap):
    exp = names(analysis_experts(tshark, cap("vrci_unacked"),
                                 prefs={"eglink.vrci_ack_timeout_ms": 1000}))
    failed = [f for f, n in exp.items() if "eglink.analysis.vrci_unacked" in n]
    # The retransmission at 1.2 s is exactly 1000 ms after the first (not later): the
    # VRPO at 1.24 s is the first packet past the deadline.
    assert failed == [34]
    # The same Command ID 100 ms after the previous transmission is still a retransmission.
    assert exp[36] == ["eglink.analysis.retransmission"]


def test_vrco_vrai_and_unknown_acks(tshark, cap):
    assert analysis_experts(tshark, cap("vrco")) == {
        3: [("eglink.analysis.unknown_ack",
             "Acknowledges VRCI command 40, which is not in the capture")],
        11: [("eglink.analysis.retransmission",
              "Retransmission of VRCO command 3 (first sent in frame 8)")],
        18: [("eglink.analysis.unknown_ack",
              "Acknowledges VRCO command 2, which is not in the capture")],
    }
    fields = ["eglink.analysis.retransmission_of", "eglink.analysis.ack_in",
              "eglink.analysis.ack_to", "eglink.analysis.ack_time"]
    assert cols(tshark, cap("vrco"), fields, two_pass=True) == {
        8: ("", "12", "", ""),
        11: ("8", "12", "", ""),
        12: ("", "", "8", "0.115000000"),
    }


def test_vrco_not_acknowledged_and_late_ack(tshark, cap):
    exp = analysis_experts(tshark, cap("vrco_unacked"))
    assert {f: v for f, v in exp.items() if v[0][0] != "eglink.analysis.retransmission"} == {
        46: [("eglink.analysis.vrco_unacked",
              "VRCO command 4 (frame 5) not acknowledged by a VRAI within 2000 ms")],
        89: [("eglink.analysis.vrco_unacked",
              "VRCO command 5 (frame 52) not acknowledged by a VRAI within 2000 ms")],
        94: [("eglink.analysis.late_ack",
              "Acknowledges command 5 2.300 s after its first transmission (frame 52), "
              "later than 2000 ms")],
    }
    assert sorted(f for f, v in exp.items() if v[0][0] == "eglink.analysis.retransmission") == \
        [8, 11, 14, 16]
    assert cols(tshark, cap("vrco_unacked"), ["eglink.analysis.ack_to", "eglink.analysis.ack_time"]) \
        == {94: ("52", "2.300000000")}


def test_vrco_timeout_preference(tshark, cap):
    exp = names(analysis_experts(tshark, cap("vrco_unacked"),
                                 prefs={"eglink.vrco_ack_timeout_ms": 2500}))
    assert [f for f, n in exp.items() if "eglink.analysis.vrco_unacked" in n] == [56]
    assert not [f for f, n in exp.items() if "eglink.analysis.late_ack" in n]


# --- VRPO reassembly --------------------------------------------------------------

REASM = ["eglink.packet_number", "eglink.reassembled_in", "eglink.reassembled.length",
         "eglink.fragment", "eglink.fragment.count"]


def test_vrpo_split_reassembled(tshark, cap):
    rows = cols(tshark, cap("vrpo_split"), REASM, two_pass=True)
    assert rows == {
        1: ("0", "3", "", "", ""), 2: ("1", "3", "", "", ""), 3: ("2", "", "1200", "1,2,3", "3"),
        4: ("0", "6", "", "", ""), 5: ("1", "6", "", "", ""), 6: ("2", "", "1200", "4,5,6", "3"),
    }
    assert analysis_experts(tshark, cap("vrpo_split")) == {}
    # The reassembled periodic data is decoded as eglink.periodic_data on the last frame.
    data = tshark.field(cap("vrpo_split"), "eglink.periodic_data", display_filter="frame.number == 3")
    parts = data[0].split(",")
    assert len(parts) == 2 and len(parts[0]) == 2 * 224 and len(parts[1]) == 2 * 1200
    info = tshark.field(cap("vrpo_split"), "_ws.col.Info", display_filter="frame.number == 3")
    assert info == ["VRPO Pkt=2 224 bytes [Reassembled 1200 bytes]"]


def test_vrpo_reassembly_off(tshark, cap):
    rows = cols(tshark, cap("vrpo_split"), REASM[1:], prefs={"eglink.reassemble_vrpo": "FALSE"},
                two_pass=True)
    assert rows == {}


def test_vrpo_burst_ends_at_next_packet_0(tshark, cap):
    """976 bytes = two full packets: without the size, the next packet 0 ends the burst."""
    rows = cols(tshark, cap("vrpo_size"), REASM, two_pass=True)
    assert rows == {
        1: ("0", "3", "", "", ""), 2: ("1", "3", "", "", ""),
        3: ("0", "5", "976", "1,2", "2"), 4: ("1", "5", "", "", ""),
        5: ("0", "", "976", "3,4", "2"), 6: ("1", "", "", "", ""),
    }


def test_vrpo_periodic_size_preference(tshark, cap):
    rows = cols(tshark, cap("vrpo_size"), REASM, prefs={"eglink.periodic_size": 976},
                two_pass=True)
    assert rows == {
        1: ("0", "2", "", "", ""), 2: ("1", "", "976", "1,2", "2"),
        3: ("0", "4", "", "", ""), 4: ("1", "", "976", "3,4", "2"),
        5: ("0", "6", "", "", ""), 6: ("1", "", "976", "5,6", "2"),
    }
    assert analysis_experts(tshark, cap("vrpo_size"), prefs={"eglink.periodic_size": 976}) == {}


def test_vrpo_burst_size_differs_from_preference(tshark, cap):
    exp = analysis_experts(tshark, cap("vrpo_split"), prefs={"eglink.periodic_size": 1000})
    assert exp == {f: [("eglink.analysis.burst_size",
                        "VRPO burst carries 1200 bytes of periodic data; the periodic data size "
                        "preference says 1000")] for f in (3, 6)}


def test_vrpo_incomplete_bursts(tshark, cap):
    incomplete = "VRPO burst from frame %d is incomplete (packet %d missing): its periodic data " \
                 "cannot be reassembled"
    lost = "1 packet lost from this sender: serial %d expected, %d received"
    assert analysis_experts(tshark, cap("vrpo_incomplete")) == {
        2: [("eglink.analysis.serial_gap", lost % (1, 2)),
            ("eglink.analysis.burst_incomplete", incomplete % (1, 1))],
        3: [("eglink.analysis.serial_gap", lost % (3, 4))],
        4: [("eglink.analysis.burst_incomplete", incomplete % (3, 0))],
        7: [("eglink.analysis.serial_gap", lost % (8, 9))],
    }
    assert cols(tshark, cap("vrpo_incomplete"), ["eglink.analysis.incomplete_burst"]) == \
        {2: ("1",), 4: ("3",)}
    # Packets 0 and 1 (full) followed by a new packet 0 look complete without the size ...
    assert cols(tshark, cap("vrpo_incomplete"), ["eglink.reassembled.length"], two_pass=True) == \
        {7: ("976",), 9: ("1200",)}
    # ... with the size, the missing packet 2 is found.
    exp = analysis_experts(tshark, cap("vrpo_incomplete"), prefs={"eglink.periodic_size": 1200})
    assert exp[7] == [("eglink.analysis.serial_gap", lost % (8, 9)),
                      ("eglink.analysis.burst_incomplete", incomplete % (5, 2))]
    assert cols(tshark, cap("vrpo_incomplete"), ["eglink.reassembled.length"],
                prefs={"eglink.periodic_size": 1200}, two_pass=True) == {9: ("1200",)}


# --- BUs --------------------------------------------------------------------------

def test_two_bus_kept_apart(tshark, cap):
    rows = cols(tshark, cap("two_bus"), ["eglink.type", "eglink.analysis.bu_stream",
                                         "eglink.analysis.bu_origin", "eglink.analysis.ack_to",
                                         "eglink.analysis.ack_time", "eglink.analysis.ack_in"],
                display_filter="eglink.command_id", two_pass=True)
    assert rows == {
        13: ("VRCI", "0", "0x1001", "", "", "18"),
        14: ("VRCI", "1", "0x1002", "", "", "15"),
        15: ("VRAO", "1", "0x1002", "14", "0.020000000", ""),
        18: ("VRAO", "0", "0x1001", "13", "0.060000000", ""),
    }
    assert analysis_experts(tshark, cap("two_bus")) == {
        27: [("eglink.analysis.serial_gap",
              "1 packet lost from this sender: serial 5 expected, 6 received")]}
    # Controller packets carry origin 0 but belong to their BU.
    streams = cols(tshark, cap("two_bus"), ["eglink.analysis.bu_origin"],
                   display_filter='eglink.type == "VRPO"')
    assert set(streams.values()) == {("0x1001",), ("0x1002",)}


def test_bu_state_changes(tshark, cap):
    exp = {f: v for f, v in analysis_experts(tshark, cap("session")).items()}
    changes = {f: m for f, v in exp.items() for n, m in v if n == "eglink.analysis.bu_state_changed"}
    assert changes == {
        10: "BU state changed from Initial (0x00) to Disarmed (0x10)",
        19: "BU state changed from Disarmed (0x10) to Armed (0x11)",
        41: "BU state changed from Armed (0x11) to Stopped (0x01)",
        52: "BU state changed from Stopped (0x01) to Armed (0x11)",
    }


def test_invalid_packets_not_analysed(tshark, capture_file):
    """A bad CRC is dropped by receivers: the analysis ignores it (no serial findings)."""
    cap_ = capture_file("eglink_bad_crc.pcap")
    rows = cols(tshark, cap_, ["eglink.analysis.expected_serial", "eglink.analysis.lost"])
    last = int(tshark.field(cap_, "frame.number")[-1])
    assert rows == {}
    assert analysis_experts(tshark, cap_) == {}
    assert tshark.field(cap_, "eglink.analysis.bu_stream", display_filter="frame.number == %d" % last) == ["0"]


# --- statistics ------------------------------------------------------------------

STATS_SESSION = """
======================================================================================================================================================
EG-Link:
Topic / Item                           Count         Average       Min Val       Max Val       Rate (ms)     Percent       Burst Rate    Burst Start  
------------------------------------------------------------------------------------------------------------------------------------------------------
EG-Link base units                     60                                                      0.0204        100%          0.0400        1.240        
 BU 239.255.42.20 port 5825            60                                                      0.0204        100.00%       0.0400        1.240        
  Time in BU state (ms)                2875                                                    0.9779        4791.67%      2.5000        1.625        
   Armed (0x11)                        1375                                                    0.4677        47.83%        2.5000        1.625        
   Stopped (0x01)                      500                                                     0.1701        17.39%        1.2500        2.125        
   Initial (0x00)                      500                                                     0.1701        17.39%        1.2500        0.125        
   Disarmed (0x10)                     500                                                     0.1701        17.39%        1.2500        0.625        
  Packets                              60                                                      0.0204        100.00%       0.0400        1.240        
   VRPO                                30                                                      0.0102        50.00%        0.0100        0.000        
   VRPI                                23                                                      0.0078        38.33%        0.0100        0.000        
   VRCI                                3                                                       0.0010        5.00%         0.0100        1.125        
   VRAO                                2                                                       0.0007        3.33%         0.0100        1.240        
   VRCO                                1                                                       0.0003        1.67%         0.0100        2.125        
   VRAI                                1                                                       0.0003        1.67%         0.0100        2.200        
  VRPO interval (ms)                   29            100.00        100           100           0.0099        48.33%        0.0100        0.140        
  VRPI interval (ms)                   22            130.68        125           250           0.0075        36.67%        0.0100        0.125        
  VRCI commands (BU to controller)     2                                                       0.0007        3.33%         0.0100        1.200        
   Acknowledgement time (ms)           2             80.00         50            110           0.0007        100.00%       0.0100        1.310        
   Acknowledged                        2                                                       0.0007        100.00%       0.0100        1.300        
   Retransmissions                     1                                                       0.0003        50.00%        0.0100        1.300        
   Failed (not acknowledged in time)   0                                                       0.0000        0.00%         -             -            
  VRCO commands (controller to BU)     1                                                       0.0003        1.67%         0.0100        2.200        
   Acknowledgement time (ms)           1             40.00         40            40            0.0003        100.00%       0.0100        2.240        
   Acknowledged                        1                                                       0.0003        100.00%       0.0100        2.200        
   Retransmissions                     0                                                       0.0000        0.00%         -             -            
   Failed (not acknowledged in time)   0                                                       0.0000        0.00%         -             -            
  Lost                                 1                                                       0.0003        1.67%         0.0100        1.540        
  Repeated                             0                                                       0.0000        0.00%         -             -            
  Invalid (CRC or size, not analysed)  0                                                       0.0000        0.00%         -             -            

------------------------------------------------------------------------------------------------------------------------------------------------------
"""


def stats(tshark, capture, two_pass=False, command="eglink,stat"):
    args = ["-q", "-n", "-r", str(capture), "-z", command] + (["-2"] if two_pass else [])
    return tshark.run(args).stdout


def test_statistics_full_text(tshark, cap):
    assert stats(tshark, cap("session")) == STATS_SESSION


def test_statistics_two_pass_identical(tshark, cap):
    assert stats(tshark, cap("session"), two_pass=True) == STATS_SESSION


def test_statistics_tree_spelling(tshark, cap):
    """-z eglink,tree (the stats_tree name) prints the same table."""
    assert stats(tshark, cap("session"), command="eglink,tree") == STATS_SESSION


def test_statistics_with_filter(tshark, cap):
    """-z eglink,stat,FILTER counts only the matching packets."""
    rows = _rows(stats(tshark, cap("session"), command='eglink,stat,eglink.type == "VRPI"'))
    assert rows[("EG-Link base units", "BU 239.255.42.20 port 5825")] == 23
    assert rows[("Packets", "VRPI")] == 23
    assert rows[("Packets", "VRPO")] == 0


def _rows(text):
    """{(parent row, name): count} of a -z eglink,stat output."""
    out, parents = {}, {}
    for line in text.splitlines():
        m = re.match(r"^( *)(\S.*?)\s{2,}(\d+)\s", line)
        if not m or m.group(2) == "Topic / Item":
            continue
        depth = len(m.group(1))
        parents[depth] = m.group(2)
        out[(parents.get(depth - 1), m.group(2))] = int(m.group(3))
    return out


def test_statistics_failures_bursts_two_bus(tshark, cap):
    rows = _rows(stats(tshark, cap("vrci_unacked")))
    assert rows[("VRCI commands (BU to controller)", "Failed (not acknowledged in time)")] == 1
    assert rows[("VRCI commands (BU to controller)", "Retransmissions")] == 19
    assert rows[("BU 239.255.42.20 port 5825", "VRCI commands (BU to controller)")] == 1
    rows = _rows(stats(tshark, cap("vrpo_incomplete")))
    assert rows[("Split VRPO bursts", "Reassembled")] == 2
    assert rows[("Split VRPO bursts", "Incomplete")] == 2
    assert rows[("BU 239.255.42.20 port 5825", "Lost")] == 3
    rows = _rows(stats(tshark, cap("two_bus")))
    assert rows[("EG-Link base units", "BU 239.255.42.20 port 5825")] == 20
    assert rows[("EG-Link base units", "BU 239.255.42.21 port 5825")] == 19


# --- one pass and two passes -----------------------------------------------------

# A single pass cannot show links to later frames: the acknowledgement of a
# command and the frame a VRPO fragment is reassembled in.
FORWARD = re.compile(r"^\s*\[(Acknowledged in frame|Reassembled in): \d+")


@pytest.mark.parametrize("name", ["vrpi_gap", "vrpo_gap", "lost", "repeated", "vrci_retransmission",
                                  "vrci_unacked", "vrco", "vrco_unacked", "vrpo_split", "vrpo_size",
                                  "vrpo_incomplete", "two_bus", "session"])
def test_one_pass_equals_two_pass(tshark, cap, name):
    one = tshark.verbose(cap(name)).splitlines()
    two = tshark.verbose(cap(name), two_pass=True).splitlines()
    assert [line for line in one if not FORWARD.match(line)] == \
        [line for line in two if not FORWARD.match(line)]
    assert not [line for line in one if FORWARD.match(line) and line not in two]
