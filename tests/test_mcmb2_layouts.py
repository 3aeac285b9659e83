"""The layout table preference: captures without a Connect."""
DUPLEX = "mcmb2_duplex_noconnect.pcap"
ECL = "eclink_pnio_noconnect.pcap"


def systems(tshark, capture, **kw):
    """{frame: mcmb2.system} of every frame."""
    return {n: r["mcmb2.system"] for n, r in tshark.frames(capture, ["mcmb2.system"], **kw).items()}


def test_inferred_without_the_table(tshark, capture_file):
    """No Connect, no table: the layout is inferred once both watchdogs have
    moved twice (frame 6); frames before it are decoded on the second pass."""
    assert systems(tshark, capture_file(DUPLEX)) == {**dict.fromkeys(range(1, 6), ""), 6: "duplex"}
    assert systems(tshark, capture_file(DUPLEX), two_pass=True) == dict.fromkeys(range(1, 7), "duplex")
    tshark.expect(capture_file(DUPLEX), 1, {"mcmb2.layout": "inferred from cyclic frames 1..6",
                                            "mcmb2.layout_entry": "0xc010/0xc011=duplex:8/4@4",
                                            "mcmb2.uplink_data": "0102030405060708"}, two_pass=True)


def test_duplex_from_the_table(tshark, capture_file):
    prefs = {"mcmb2.layouts": "0xC010/0xC011=duplex:8/4"}
    tshark.expect(capture_file(DUPLEX), 1, {"mcmb2.status": 1, "mcmb2.terminal": 3,
                                            "mcmb2.uplink_data": "0102030405060708", "mcmb2.base_unit": None,
                                            "mcmb2.downlink_data": None, "mcmb2.layout": "preference"}, prefs=prefs)
    tshark.expect(capture_file(DUPLEX), 2, {"mcmb2.status": None, "mcmb2.terminal": None, "mcmb2.uplink_data": None,
                                            "mcmb2.base_unit": 2, "mcmb2.downlink_data": "09080706",
                                            "mcmb2.layout": "preference"}, prefs=prefs)


def test_uplink_only_entry(tshark, capture_file):
    got = tshark.frames(capture_file(DUPLEX), ["mcmb2.direction"], prefs={"mcmb2.layouts": "49168=duplex:8/4"})
    assert {n: r["mcmb2.direction"] for n, r in got.items()} == \
        {1: "uplink", 2: "", 3: "uplink", 4: "", 5: "uplink", 6: ""}


def test_wrong_sizes_are_flagged_not_crashed(tshark, capture_file):
    # 4 DAP IOPS + header (3) + 20+1 + 20+1 + 1 IOCS = 50 bytes > the 40-byte C-SDU
    ex = tshark.experts(capture_file(DUPLEX), prefs={"mcmb2.layouts": "0xC010=duplex:40"})
    assert ex[1] == ["C-SDU has 40 bytes, the layout needs 50"]


def test_bad_table_entries_are_ignored(tshark, capture_file):
    got = systems(tshark, capture_file(DUPLEX),
                  prefs={"mcmb2.layouts": "garbage; 0xZZ=duplex; 0xC010/0xC011=duplex:8/4; 5=weird"})
    assert got == dict.fromkeys(range(1, 7), "duplex")


def test_eclink_from_the_table(tshark, capture_file):
    prefs = {"mcmb2.layouts": "0xC020/0xC021=eclink:/20"}
    tshark.expect(capture_file(ECL), 1, {"eclink.image": "input", "eclink.pci": 1, "eclink.pco": None,
                                         "eclink_pnio.layout": "preference"}, prefs=prefs)
    tshark.expect(capture_file(ECL), 2, {"eclink.image": "output", "eclink.pci": None, "eclink.pco": 1,
                                         "eclink_pnio.layout": "preference"}, prefs=prefs)


PCWORX = "mcmb2_duplex_pcworx.pcap"
ECL_DATA_FIRST = "eclink_pnio_data_first.pcap"


def test_frame_order_from_the_table(tshark, capture_file):
    """[UP/DOWN]: where the controller put each element (PC WORX: the IOCS
    first); with the heuristic off the table alone decodes it."""
    prefs = {"mcmb2.layouts": "0xC012/0xC013=duplex:26/2,a8@4[3c,4d,h,20,4,2]", "mcmb2.heuristic": "FALSE"}
    got = tshark.frames(capture_file(PCWORX), ["mcmb2.layout", "mcmb2.uplink_data", "mcmb2.downlink_data"],
                        prefs=prefs)
    # the payload of tools/capgen (profinet.py _duplex_payload(26, 0))
    assert got[1] == {"mcmb2.layout": "preference", "mcmb2.uplink_data": (b"\x01" + bytes(range(1, 26))).hex(),
                      "mcmb2.downlink_data": ""}
    assert got[2] == {"mcmb2.layout": "preference", "mcmb2.uplink_data": "",
                      "mcmb2.downlink_data": (bytes([9, 8]) + b"HOIST UP").hex()}
    prefs = {"mcmb2.layouts": "0xC022/0xC023=eclink:/224@4[c,4d,i/i,4d,c]", "mcmb2.heuristic": "FALSE"}
    got = tshark.frames(capture_file(ECL_DATA_FIRST), ["eclink.pci", "eclink.pco"], prefs=prefs)
    assert [(r["eclink.pci"], r["eclink.pco"]) for _, r in sorted(got.items())] == \
        [("1", ""), ("", "1"), ("2", ""), ("", "2"), ("3", ""), ("", "3"), ("4", ""), ("", "4")]


def test_frame_orders_that_do_not_fit_are_ignored(tshark, capture_file):
    """An order naming an element too few or too many, an unknown item or an
    order on a polled entry without sizes: the entry is skipped."""
    for entry in ("0xC012/0xC013=duplex:26/2,a8@4[3c,4d,h,20,4]", "0xC012/0xC013=duplex:26/2,a8@4[3c,4d,h,20,4,2,c]",
                  "0xC012/0xC013=duplex:26/2,a8@4[3c,4d,h,20,4,x]", "0xC012/0xC013=polled@4[3c,4d,h,20,4,2]",
                  "0xC012/0xC013=duplex:26/2,a8@4[3c,4d,h,20,4,a2]"):
        got = systems(tshark, capture_file(PCWORX), prefs={"mcmb2.layouts": entry, "mcmb2.heuristic": "FALSE"})
        assert set(got.values()) == {""}, entry
