"""EG-Link CRC: CRC-32/MPEG-2 little-endian by default, the other variants and byte
orders by preference, and a hint naming the variant that matches a failing CRC."""
import pytest

from eglink_testlib import gen, messages

VARIANT_NAMES = {"mpeg2": "CRC-32/MPEG-2", "bzip2": "CRC-32/BZIP2",
                 "iso_hdlc": "CRC-32/ISO-HDLC", "stm32": "STM32 hardware CRC"}
ORDER_NAMES = {"le": "little-endian", "be": "big-endian"}
GOOD_CAPTURES = ["eglink_armed.pcap", "eglink_disarmed.pcap", "eglink_states.pcap",
                 "eglink_commands.pcap", "eglink_vrpo_split.pcap", "eglink_range.pcap",
                 "eglink_header.pcap", "eglink_heuristic.pcap", "eglink_unknown_type.pcap"]


def hint(variant, order):
    return ("CRC matches %s, %s: set the preference (eglink.crc_variant: %s, "
            "eglink.crc_byte_order: %s)" % (VARIANT_NAMES[variant], ORDER_NAMES[order],
                                            variant, order))


def test_check_values():
    assert gen.crc32_mpeg2(b"123456789") == 0x0376E6E7
    assert gen.crc32_stm32(b"1234") == gen.crc32_mpeg2(b"4321")


@pytest.mark.parametrize("name", GOOD_CAPTURES)
def test_good_crc(tshark, capture_file, name):
    status = tshark.field(capture_file(name), "eglink.crc.status", display_filter="eglink.crc")
    assert status and set(status) == {"1"}


def test_bad_crc(tshark, capture_file):
    cap = capture_file("eglink_bad_crc.pcap")
    rows = tshark.fields(cap, ["eglink.type", "eglink.crc", "eglink.crc.status", "udp.payload"])
    assert [r[2] for r in rows] == ["0"] * 6 + ["1"]
    assert [r[1] for r in rows][:6] == ["0xdeadbeef", "0x00000000", "0x12345678", "0xffffffff",
                                        "0xcafef00d", "0x0badc0de"]
    expected = {}
    for n, r in enumerate(rows[:6], 1):
        body = bytes.fromhex(r[3])[:-4]
        expected[n] = ["Bad CRC [should be 0x%08x]" % gen.crc32_mpeg2(body)]
    assert messages(tshark, cap) == expected
    assert tshark.field(cap, "_ws.col.Info")[0] == "VRPI Armed RU=0xbeef Enabled [bad CRC]"


def test_variant_hints_with_default_preferences(tshark, capture_file):
    got = messages(tshark, capture_file("eglink_crc_variants.pcap"))
    expected = {}
    for group, (variant, order) in enumerate(gen.CRC_VARIANTS):
        if group == 0:
            continue
        for k in range(3):
            frame = 3 * group + k + 1
            expected[frame] = [got.get(frame, ["?"])[0], hint(variant, order)]
            assert got[frame][0].startswith("Bad CRC [should be 0x")
    assert got == expected


@pytest.mark.parametrize("variant, order", gen.CRC_VARIANTS)
def test_preference_selects_variant(tshark, capture_file, variant, order):
    cap = capture_file("eglink_crc_variants.pcap")
    prefs = {"eglink.crc_variant": variant, "eglink.crc_byte_order": order}
    status = tshark.field(cap, "eglink.crc.status", prefs=prefs)
    group = gen.CRC_VARIANTS.index((variant, order))
    assert status == ["1" if n // 3 == group else "0" for n in range(24)]
    got = messages(tshark, cap, prefs=prefs)
    # MPEG-2 little-endian frames are now the ones that get a hint
    if group != 0:
        assert got[1][1] == hint("mpeg2", "le")
    assert not any(n // 3 == group for n in (f - 1 for f in got))


@pytest.mark.parametrize("variant, order", gen.CRC_VARIANTS)
def test_crc_value_in_configured_byte_order(tshark, capture_file, variant, order):
    cap = capture_file("eglink_crc_variants.pcap")
    group = gen.CRC_VARIANTS.index((variant, order))
    rows = tshark.fields(cap, ["eglink.crc", "udp.payload"],
                         prefs={"eglink.crc_variant": variant, "eglink.crc_byte_order": order},
                         display_filter="frame.number == %d" % (3 * group + 1))
    body = bytes.fromhex(rows[0][1])[:-4]
    assert rows[0][0] == "0x%08x" % gen.CRC[variant](body)


def test_crc_status_filter(tshark, capture_file):
    rows = tshark.fields(capture_file("eglink_bad_crc.pcap"), ["frame.number"],
                         display_filter="eglink.crc.status == 0")
    assert [r[0] for r in rows] == ["1", "2", "3", "4", "5", "6"]
    rows = tshark.fields(capture_file("eglink_bad_crc.pcap"), ["frame.number"],
                         display_filter="eglink.crc.bad")
    assert len(rows) == 6
