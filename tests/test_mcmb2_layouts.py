"""The layout table preference: captures without a Connect."""
DUPLEX = "mcmb2_duplex_noconnect.pcap"
ECL = "eclink_pnio_noconnect.pcap"


def test_not_decoded_without_the_table(tshark, capture_file):
    assert tshark.field(capture_file(DUPLEX), "mcmb2.system") == [""] * 6


def test_duplex_from_the_table(tshark, capture_file):
    rows = tshark.fields(capture_file(DUPLEX), ["frame.number", "mcmb2.status", "mcmb2.terminal",
                                                "mcmb2.uplink_data", "mcmb2.base_unit", "mcmb2.downlink_data",
                                                "mcmb2.layout"],
                         prefs={"mcmb2.layouts": "0xC010/0xC011=duplex:8/4"})
    assert rows[0] == ["1", "0x01", "3", "0102030405060708", "", "", "preference"]
    assert rows[1] == ["2", "", "", "", "2", "09080706", "preference"]


def test_uplink_only_entry(tshark, capture_file):
    rows = tshark.fields(capture_file(DUPLEX), ["mcmb2.direction"],
                         prefs={"mcmb2.layouts": "49168=duplex:8/4"})
    assert [r[0] for r in rows] == ["uplink", ""] * 3


def test_wrong_sizes_are_flagged_not_crashed(tshark, capture_file):
    # 4 DAP IOPS + header (3) + 20+1 + 20+1 + 1 IOCS = 50 bytes > the 40-byte C-SDU
    ex = tshark.experts(capture_file(DUPLEX), prefs={"mcmb2.layouts": "0xC010=duplex:40"})
    assert ex[1] == ["C-SDU has 40 bytes, the layout needs 50"]


def test_bad_table_entries_are_ignored(tshark, capture_file):
    rows = tshark.fields(capture_file(DUPLEX), ["mcmb2.system"],
                         prefs={"mcmb2.layouts": "garbage; 0xZZ=duplex; 0xC010/0xC011=duplex:8/4; 5=weird"})
    assert [r[0] for r in rows] == ["duplex"] * 6


def test_eclink_from_the_table(tshark, capture_file):
    rows = tshark.fields(capture_file(ECL), ["frame.number", "eclink.image", "eclink.pci", "eclink.pco",
                                             "eclink_pnio.layout"],
                         prefs={"mcmb2.layouts": "0xC020/0xC021=eclink:/20"})
    assert rows[0] == ["1", "input", "1", "", "preference"]
    assert rows[1] == ["2", "output", "", "1", "preference"]
