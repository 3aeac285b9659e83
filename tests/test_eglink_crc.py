"""EG-Link CRC: CRC-32/MPEG-2 little-endian by default, the other variants and byte
orders by preference, and a hint naming the variant that matches a failing CRC."""
import random

import pytest

from eglink_testlib import expect_frames, gen, messages

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
    cap = capture_file(name)
    with_crc = tshark.frames(cap, ["eglink.crc.status"], display_filter="eglink.crc")
    assert with_crc
    expect_frames(tshark, cap, {n: {"eglink.crc.status": 1} for n in with_crc},
                  display_filter="eglink.crc")


CORRUPTED = ": no CRC variant fits, the packet is corrupted: its payload values are not trusted, none is judged"
VRPO_FRAGMENT_MAX = 488  # TS-0006: a VRPO carries at most 488 bytes of periodic data
BAD_CRCS = ["0xdeadbeef", "0x00000000", "0x12345678", "0xffffffff", "0xcafef00d", "0x0badc0de"]


def test_bad_crc(tshark, capture_file):
    cap = capture_file("eglink_bad_crc.pcap")
    got = expect_frames(tshark, cap, {
        **{n: {"eglink.crc": crc, "eglink.crc.status": 0} for n, crc in enumerate(BAD_CRCS, 1)},
        7: {"eglink.crc.status": 1}})
    assert sorted(got) == list(range(1, 8))
    payloads = tshark.frames(cap, ["udp.payload"])
    expected = {n: [("Bad CRC [should be 0x%08x]" + CORRUPTED) % gen.crc32_mpeg2(
        bytes.fromhex(payloads[n]["udp.payload"])[:-4])] for n in range(1, 7)}
    assert messages(tshark, cap) == expected


def test_bad_crc_info_tag(tshark, capture_file):
    """[bad CRC] on every packet type, after what the packet says."""
    expect_frames(tshark, capture_file("eglink_bad_crc.pcap"), {
        1: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled [bad CRC]"},
        2: {"_ws.col.Info": "VRPO Pkt=0 64 bytes [bad CRC]"},
        3: {"_ws.col.Info": "VRCI Cmd=9 [bad CRC]"},
        4: {"_ws.col.Info": "VRAO Cmd=9 [bad CRC]"},
        5: {"_ws.col.Info": "VRCO Cmd=4 [bad CRC]"},
        6: {"_ws.col.Info": "VRAI Cmd=4 [bad CRC]"},
        7: {"_ws.col.Info": "VRPI BU=Armed RU 0xbeef=Enabled"},
    })


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
    group = gen.CRC_VARIANTS.index((variant, order))
    # frames 3g+1..3g+3 carry the CRC of variant group g
    got = expect_frames(tshark, cap, {n: {"eglink.crc.status": 1 if (n - 1) // 3 == group else 0}
                                      for n in range(1, 25)}, prefs=prefs)
    assert len(got) == 24
    got = messages(tshark, cap, prefs=prefs)
    # MPEG-2 little-endian frames are now the ones that get a hint
    if group != 0:
        assert got[1][1] == hint("mpeg2", "le")
    assert not any(n // 3 == group for n in (f - 1 for f in got))


@pytest.mark.parametrize("variant, order", gen.CRC_VARIANTS)
def test_crc_value_in_configured_byte_order(tshark, capture_file, variant, order):
    cap = capture_file("eglink_crc_variants.pcap")
    frame = 3 * gen.CRC_VARIANTS.index((variant, order)) + 1
    prefs = {"eglink.crc_variant": variant, "eglink.crc_byte_order": order}
    body = bytes.fromhex(tshark.frame(cap, frame, ["udp.payload"])["udp.payload"])[:-4]
    tshark.expect(cap, frame, {"eglink.crc": "0x%08x" % gen.CRC[variant](body)}, prefs=prefs)


def test_crc_status_filter(tshark, capture_file):
    cap = capture_file("eglink_bad_crc.pcap")
    assert sorted(tshark.frames(cap, [], display_filter="eglink.crc.status == 0")) == \
        [1, 2, 3, 4, 5, 6]
    assert sorted(tshark.frames(cap, [], display_filter="eglink.crc.bad")) == [1, 2, 3, 4, 5, 6]


def test_bad_crc_is_a_checksum_error(tshark, capture_file):
    shown = tshark.frames(capture_file("eglink_bad_crc.pcap"), [],
                          display_filter="eglink.crc.bad && _ws.expert.severity == error"
                                         " && _ws.expert.group == checksum")
    assert sorted(shown) == [1, 2, 3, 4, 5, 6]


def test_corrupted_values_are_not_judged(tshark, work_dir):
    """A VRPI whose bytes were corrupted (BU state 0x05, battery 101 %, joystick 1 at
    1001) with a CRC no variant fits: one error says its values are not trusted, no
    undefined-value error, no finding on its values, no [undefined]; the fields
    still decode. The same values
    with a good CRC, or with the CRC of another variant (the packet is intact), are
    judged."""
    bad = gen.armed(bu_state=0x05, battery=101, joysticks=(1001, 0, 0, 0))
    link = gen.Link()
    link.bu(0.0, "VRPI", bad, crc_value=0xDEADBEEF)
    link.bu(0.125, "VRPI", bad)
    link.bu(0.25, "VRPI", bad, crc="bzip2", crc_order="be")
    cap = work_dir / "corrupted_values.pcap"
    cap.write_bytes(link.cap.to_bytes())
    cap.chmod(0o644)
    got = messages(tshark, cap)
    judged = ["BU state Unknown (0x05): not defined in TS-0006",
              "ES-Link relays open: BU state Unknown (0x05), an undefined state below Disarmed",
              "RU battery 101 % is above 100 %", "Joystick 1 position 1001 is outside -1000..+1000"]
    assert got[1] == [("Bad CRC [should be 0x%08x]" + CORRUPTED)
                      % gen.crc32_mpeg2(gen.packet("VRPI", bad, origin=link.origin)[:-4])]
    assert got[2] == judged
    assert got[3] == judged + [got[3][-2], hint("bzip2", "be")]
    assert got[3][-2].startswith("Bad CRC [should be 0x") and got[3][-2].endswith("]")
    expect_frames(tshark, cap, {
        1: {"_ws.col.Info": "VRPI BU=Unknown (0x05) RU 0xbeef=Enabled J1=1001 [relays open] [bad CRC]",
            "eglink.bu_state": 5, "eglink.ru_battery": 101, "eglink.joystick1": 1001},
        2: {"_ws.col.Info": "VRPI BU=Unknown (0x05) RU 0xbeef=Enabled J1=1001 [relays open] [undefined]"}})


def test_crc_over_every_length(tshark, work_dir):
    """The CRC is computed sixteen bytes a step, then four, then the last one
    to three: VRPOs with every fragment length 0..488 (the CRC over 18..506
    bytes: every length modulo 16, with random bytes) check Good, and the same packets with
    their CRC off by one bit check Bad with the CRC the spec's bitwise
    algorithm gives (the capture generator's) in the message."""
    rng = random.Random(20261202)
    link = gen.Link()
    bodies = {}
    for length in range(0, VRPO_FRAGMENT_MAX + 1):
        payload = gen.vrpo(length % 65536, bytes(rng.randrange(256) for _ in range(length)))
        bad = length % 2 == 1
        frame = link.ctrl(0.01 * length, "VRPO", payload,
                          crc_value=None if not bad else gen.crc32_mpeg2(
                              gen.packet("VRPO", payload, serial=link.ctrl_serial)[:-4]) ^ 1)
        bodies[frame] = bad
    cap = work_dir / "crc_lengths.pcap"
    cap.write_bytes(link.cap.to_bytes())
    cap.chmod(0o644)
    got = tshark.frames(cap, ["eglink.crc.status", "udp.payload"])
    assert sorted(got) == sorted(bodies)
    wrong = [n for n, bad in bodies.items() if got[n]["eglink.crc.status"] != ("0" if bad else "1")]
    assert not wrong, "frames with the wrong CRC status: %s" % wrong[:20]
    shown = messages(tshark, cap)
    for n, bad in bodies.items():
        if bad:
            body = bytes.fromhex(got[n]["udp.payload"])[:-4]
            assert shown[n][0].startswith("Bad CRC [should be 0x%08x]" % gen.crc32_mpeg2(body)), (n, shown[n])
