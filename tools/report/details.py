"""The detail a finding's line needs: the value that is wrong and where.

The catalog's text says what kind of fact it is ("undefined slot status");
the reader also needs the value and its place ("0x03 in slot 3") to act on
it. Each function reads the value fields of the same row (rows.FIELDS) and
returns the text that follows the catalog's, or "" when the row does not
carry the value (an older plugin, a cut packet).
"""
from .rows import COL

LINK_STATES = 6          # EG-Link and EC-Link link status: 0..6 defined
RU_DISABLED = 3          # RU disabled reason: 0..3 defined
SLOT_STATUS = (0x0, 0x1, 0x2, 0x7, 0xF)


def values(c, name):
    """The occurrences of one field in the row (several for repeated items)."""
    text = c[COL[name]]
    return [v for v in text.split(",") if v] if text else []


def ints(c, name):
    return [int(v, 0) for v in values(c, name)]


def first_bad(c, names, bad):
    """(label, value) of the first of the fields whose value is bad."""
    for name, label in names:
        for v in ints(c, name):
            if bad(v):
                return label, v
    return None


def hexed(c, name, sep=" "):
    vals = ints(c, name)
    return "%s0x%02X" % (sep, vals[-1]) if vals else ""


def raw(c, name, fmt):
    vals = values(c, name)
    return fmt % vals[-1] if vals else ""


def bad_of(names, bad, fmt):
    def detail(c):
        hit = first_bad(c, names, bad)
        return fmt % hit if hit else ""
    return detail


def link_names(proto):
    return [("%s.%s_link_status" % (proto, k), "%s-Link status" % k.upper().replace("_", "-"))
            for k in ("eg", "ec", "c")]


def joysticks(proto):
    return [("%s.joystick%d" % (proto, i), "joystick %d" % i) for i in range(1, 5)]


def flags(proto):
    return [("%s.ru_cable" % proto, "RU cable"), ("%s.ru_docked" % proto, "RU docked"),
            ("%s.encoder_switch" % proto, "encoder switch")]


def slot_status(c):
    for slot, status in zip(values(c, "mcmb2.slot"), ints(c, "mcmb2.slot.status")):
        if status not in SLOT_STATUS:
            return " 0x%02X in slot %s" % (status, slot)
    return ""


def udp_payload(c):
    vals = ints(c, "udp.length")
    return vals[-1] - 8 if vals else None


def too_short(c):
    size = udp_payload(c)
    return "" if size is None else ": %d bytes" % size


def size_mismatch(c):
    size, payload = values(c, "eglink.size"), udp_payload(c)
    if not size or payload is None:
        return ""
    return ": Size %s, UDP payload %d bytes" % (size[-1], payload)


def size_invalid(c):
    typ, size = values(c, "eglink.type"), values(c, "eglink.size")
    return ": %s with a %s-byte payload" % (typ[-1], size[-1]) if typ and size else ""


def layout_seen(c):
    y, z = values(c, "mcmb2.uplink_size"), values(c, "mcmb2.downlink_size")
    return ": the frame has Y=%s, Z=%s" % (y[-1], z[-1]) if y and z else ""


def percent(proto):
    return bad_of([("%s.ru_battery" % proto, "RU battery"), ("%s.ru_rssi" % proto, "RU RSSI")],
                  lambda v: v > 100, ": %s %d %%")


def periodic_block(c):
    block, size = values(c, "eclink.periodic_block"), values(c, "eclink.periodic_size")
    if not block:
        return ""
    return ": block %s%s" % (block[-1], " of %s bytes" % size[-1] if size else "")


def above(limit):
    return lambda v: v > limit


def out_of_joystick_range(v):
    return v < -1000 or v > 1000


# expert field: the function that gives its detail
DETAILS = {
    "eglink.too_short": too_short,
    "eglink.size.mismatch": size_mismatch,
    "eglink.size.invalid": size_invalid,
    "eglink.type.unknown": lambda c: raw(c, "eglink.type", " %s"),
    "eglink.revision.unknown": lambda c: raw(c, "eglink.revision", " %s"),
    "eglink.origin.nonzero": lambda c: raw(c, "eglink.origin", ": %s"),
    "eglink.spare.nonzero": lambda c: raw(c, "eglink.spare", ": %s"),
    "eglink.payload_spare.nonzero": lambda c: raw(c, "eglink.payload_spare", ": bytes %s"),
    "eglink.bu_state.unknown": lambda c: hexed(c, "eglink.bu_state"),
    "eglink.link_status.unknown": bad_of(link_names("eglink"), above(LINK_STATES), ": %s 0x%02X"),
    "eglink.vlaps.range": lambda c: raw(c, "eglink.vlaps", ": %s"),
    "eglink.ru_state.unknown": lambda c: hexed(c, "eglink.ru_state"),
    "eglink.ru_battery.range": lambda c: raw(c, "eglink.ru_battery", ": %s %%"),
    "eglink.ru_rssi.range": lambda c: raw(c, "eglink.ru_rssi", ": %s %%"),
    "eglink.flag.invalid": bad_of(flags("eglink"), above(1), ": %s 0x%02X"),
    "eglink.ru_disabled.unknown": lambda c: hexed(c, "eglink.ru_disabled"),
    "eglink.joystick.range": bad_of(joysticks("eglink"), out_of_joystick_range, ": %s at %d"),
    "eglink.analysis.retransmission": lambda c: raw(c, "eglink.analysis.retransmission_of",
                                                    ": first sent in frame %s"),
    "eglink.analysis.origin_changed": lambda c: raw(c, "eglink.origin", ": %s"),
    "eglink.analysis.serial_corrupted": lambda c: raw(c, "eglink.analysis.corrupted_in",
                                                      ": arrived in frame %s"),
    "eglink.analysis.wrong_port": lambda c: raw(c, "udp.dstport", ": port %s"),
    "mcmb2.status.undefined": lambda c: hexed(c, "mcmb2.status"),
    "mcmb2.slot.status.undefined": slot_status,
    "mcmb2.terminal.not_zero": lambda c: raw(c, "mcmb2.terminal", ": terminal %s"),
    "mcmb2.layout_mismatch": layout_seen,
    "mcmb2.iops.bad": bad_of([("mcmb2.iops", "")], lambda v: v != 0x80, ":%s 0x%02X"),
    "mcmb2.iocs.bad": bad_of([("mcmb2.iocs", "")], lambda v: v != 0x80, ":%s 0x%02X"),
    "mcmb2.reserved.not_zero": bad_of([("mcmb2.reserved", "")], above(0), ":%s 0x%02X"),
    "eclink.bu_state.unknown": lambda c: hexed(c, "eclink.bu_state"),
    "eclink.vlaps.range": lambda c: raw(c, "eclink.vlaps", ": %s"),
    "eclink.link_status.range": bad_of(link_names("eclink"), above(LINK_STATES), ": %s 0x%02X"),
    "eclink.ru_state.range": lambda c: hexed(c, "eclink.ru_state"),
    "eclink.percent.range": percent("eclink"),
    "eclink.bool.range": bad_of(flags("eclink"), above(1), ": %s 0x%02X"),
    "eclink.ru_disabled.range": lambda c: hexed(c, "eclink.ru_disabled"),
    "eclink.joystick.range": bad_of(joysticks("eclink"), out_of_joystick_range, ": %s at %d"),
    "eclink.spare.not_zero": lambda c: raw(c, "eclink.spare", ": bytes %s"),
    "eclink.periodic_size.range": lambda c: raw(c, "eclink.periodic_size", ": %s bytes"),
    "eclink.periodic_block.range": periodic_block,
    "eclink_pnio.iops.bad": bad_of([("eclink_pnio.iops", "")], lambda v: v != 0x80, ":%s 0x%02X"),
}
