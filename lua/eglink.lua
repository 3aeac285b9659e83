--[[ eglink.lua -- VisionRemote EG-Link (VM-110 UDP EG-Link, TS-0006), protocol
"eglink", for a Wireshark without the EG-Link C plugin (plugins/vrshark): the
same fields, expert infos, columns, heuristic, ports and preferences as
plugins/vrshark/packet-eglink.c, which stays the reference. Where the C plugin
is loaded it decodes EG-Link and this file registers nothing.

Every EG-Link packet is one UDP datagram, all integers little-endian:

  0   4  Packet ID   "VR" + P/C/A (periodic, command, acknowledge)
                          + I/O (input = BU to machine controller,
                                 output = machine controller to BU)
  4   2  Revision    0 = the layout decoded here
  6   2  Origin      unique ID of the sending BU, 0 from the controller
  8   2  Serial      sequential per sender
 10   2  Size        payload length (= UDP payload length - 20)
 12   4  Spare       0
 16   n  Payload     VRPI 46, VRPO 2..490, VRCI/VRCO 22, VRAI/VRAO 2
16+n  4  CRC         CRC-32/MPEG-2 over ID + header + payload

Input port 5825 (configurable), output port = input port + 2, multicast
239.255.42.20. The per-BU conversation analysis, command links and VRPO
reassembly live in vrshark/eglink_analysis.luam and the modules it requires
(as eglink-analysis.c and the files beside it), the "eglink.data" hand-off in
vrshark/eglink_data.luam. The statistics tree of
the C plugin (-z eglink,tree) has no Lua counterpart; its table, -z eglink,stat,
has (docs/eglink.md).
]]

local dir = debug.getinfo(1, "S").source:match("^@(.*)[/\\]")
package.path = dir .. "/?.luam;" .. package.path

-- The C plugin (vrshark.so) registers before the Lua plugins load: its
-- transport front ends (vrshark/frontends.luam) and its "eglink.data" table
-- are there. Then EG-Link is the C plugin's, silently.
local fe = require("vrshark.frontends")
local version = require("vrshark.version")
local EGLINK_DATA_TABLE = require("vrshark.seam").EGLINK_DATA_TABLE
local function have_table(name)
    local ok, t = pcall(DissectorTable.get, name)
    return ok and t ~= nil
end
if fe.pn_frame_id ~= nil or have_table(EGLINK_DATA_TABLE) then
    set_plugin_info(version.info("VisionRemote EG-Link (TS-0006) in Lua: idle, the C plugin decodes EG-Link"))
    return
end
set_plugin_info(version.info("VisionRemote EG-Link (TS-0006) in Lua, for a Wireshark without the C plugin"))
local handoff = require("vrshark.eglink_data")

-- The conversation analysis (eglink-analysis.c in Lua). Without it (a copy
-- of this file alone) the packets are decoded, not analysed.
local analysis
if package.searchpath and package.searchpath("vrshark.eglink_analysis", package.path) then
    analysis = require("vrshark.eglink_analysis")
    analysis.stat_cmd_register() -- tshark -z eglink,stat
end

local band, bor, bxor, lshift, rshift = bit.band, bit.bor, bit.bxor, bit.lshift, bit.rshift
local byte, sub = string.byte, string.sub

-- Wireshark's Lua methods as plain functions (vrshark/api.luam: obj:method()
-- looks the method up through the class's __index on every call).
local api = require("vrshark.api")
local function method(class, name)
    local fn = class and rawget(class, name)
    if type(fn) == "function" then return fn end
    return function(obj, ...) return obj[name](obj, ...) end
end
local t_add, t_add_le, t_append, t_set_text, t_set_generated = api.add, api.add_le, api.append_text,
    api.set_text, api.set_generated
local tvb_range, tvb_raw, tvb_len, tvb_reported_len = api.range, api.raw, api.len, api.reported_len
local p_visited = api.pinfo.visited
local col_append, col_clear, col_set = method(Column, "append"), method(Column, "clear"), method(Column, "set")

local HEADER_LEN = 16
local CRC_LEN = 4
local MIN_LEN = HEADER_LEN + CRC_LEN
local VRPO_FRAGMENT_MAX = 488
local VRPI_LEN = 46
local VRPO_MIN_LEN = 2
local VRPO_MAX_LEN = 2 + VRPO_FRAGMENT_MAX
local CMD_LEN = 22
local ACK_LEN = 2
local BU_STATE_DISARMED = 0x10
local RU_STATE_STOPPED = 4
local RU_STATE_DISARMED = 1
local LINK_PASSIVE = 6
local JOYSTICK_LIMIT = 1000
local OUTPUT_PORT_OFFSET = 2
local DEFAULT_INPUT_PORTS = "5825"

local proto = Proto("eglink", "VisionRemote EG-Link")

------------------------------------------------------------------------
-- Value tables
------------------------------------------------------------------------
-- Packet types as the C plugin's eglink_type_t, by name.
local TYPE_OF_ID = {
    VRPI = "VRPI", VRPO = "VRPO", VRCI = "VRCI", VRCO = "VRCO", VRAI = "VRAI", VRAO = "VRAO",
}
local TYPE_DESCR = {
    VRPI = "Periodic Input, BU to controller",
    VRPO = "Periodic Output, controller to BU",
    VRCI = "Command Input, BU to controller",
    VRCO = "Command Output, controller to BU",
    VRAI = "Acknowledge Input, BU to controller",
    VRAO = "Acknowledge Output, controller to BU",
    UNKNOWN = "unknown packet type",
}
local IS_INPUT = { VRPI = true, VRCI = true, VRAI = true }
-- what the Packet ID item appends
local TYPE_LABEL = {}
for k, v in pairs(TYPE_DESCR) do TYPE_LABEL[k] = " (" .. v .. ")" end

local status_names = require("vrshark.status_names")
local BU_STATE = status_names.BU_STATE
-- Why the ES-Link relays are open, per BU state below Disarmed.
local BU_STATE_ADVICE = {
    [0x00] = "the BU is not fully operative yet",
    [0x01] = "the armed RU asked the BU to stop",
    [0x02] = "monitoring found an error on the EC-Link or EG-Link",
    [0x03] = "contact with the armed RU is lost: switch the RU on and arm it again",
    [0x04] = "the BU self-test found a fatal internal error",
}
local LINK_STATUS = status_names.LINK_STATUS
local RU_STATE = status_names.RU_STATE
local RU_CABLE = status_names.RU_CABLE
local RU_DOCKED = status_names.RU_DOCKED
local RU_DISABLED = {
    [0] = "Enabled", [1] = "Disabled (tilted)", [2] = "Disabled (inactivity)", [3] = "Disabled (other cause)",
}
local ENCODER_SWITCH = status_names.ENCODER_SWITCH
local RELAYS = { "Open", "Closed" }
-- Wireshark's proto_checksum_vals
local CHECKSUM_STATUS = { [0] = "Bad", [1] = "Good", [2] = "Unverified", [3] = "Not present", [4] = "Illegal" }
local CHECKSUM_BAD, CHECKSUM_GOOD = 0, 1
-- "87 %": a space before the unit, as everywhere in vrshark
local UNITS_PERCENT = { " %" }

------------------------------------------------------------------------
-- Fields (the same filter names, types, bases and value strings as the C plugin)
------------------------------------------------------------------------
local PERCENT_BASE = bor(base.DEC, base.UNIT_STRING or 0)
local pf = {
    type = ProtoField.string("eglink.type", "Packet ID", base.NONE,
        "Packet type: VRPI, VRPO, VRCI, VRCO, VRAI or VRAO"),
    revision = ProtoField.uint16("eglink.revision", "Revision", base.DEC, nil, nil,
        "Payload layout revision, 0 for TS-0006"),
    origin = ProtoField.uint16("eglink.origin", "Origin", base.HEX, nil, nil,
        "Unique ID of the sending BU, 0 from the machine controller"),
    serial = ProtoField.uint16("eglink.serial", "Serial", base.DEC, nil, nil,
        "Packet serial number, counted by the sender"),
    size = ProtoField.uint16("eglink.size", "Size", base.DEC, nil, nil, "Payload size in bytes"),
    spare = ProtoField.uint32("eglink.spare", "Spare", base.HEX, nil, nil, "Header spare, 0"),
    payload = ProtoField.none("eglink.payload", "Payload"),
    payload_spare = ProtoField.bytes("eglink.payload_spare", "Payload spare", base.NONE,
        "Payload spare bytes, 0"),
    extra_payload = ProtoField.bytes("eglink.extra_payload", "Extra payload", base.NONE,
        "Bytes beyond the payload size of this packet type"),
    unknown_payload = ProtoField.bytes("eglink.unknown_payload", "Payload data", base.NONE,
        "Payload of an unknown packet type"),
    crc = ProtoField.uint32("eglink.crc", "CRC", base.HEX, nil, nil, "CRC-32 over packet ID, header and payload"),
    crc_status = ProtoField.uint8("eglink.crc.status", "CRC status", base.DEC, CHECKSUM_STATUS),

    bu_state = ProtoField.uint8("eglink.bu_state", "BU state", base.HEX, BU_STATE, nil,
        "State of the BU; below 0x10 the ES-Link relays are open"),
    relays_open = ProtoField.bool("eglink.relays_open", "ES-Link relays", base.NONE, RELAYS, nil,
        "Open when the BU state is below Disarmed (0x10) or the armed RU is stopped"),
    vlaps = ProtoField.uint8("eglink.vlaps", "VLAPs", base.DEC, nil, nil,
        "Number of VLAPs connected to the BU (0..3)"),
    unarmed_rus = ProtoField.uint8("eglink.unarmed_rus", "Unarmed RUs", base.DEC, nil, nil,
        "Number of unarmed RUs talking to this BU"),
    eg_link_status = ProtoField.uint8("eglink.eg_link_status", "EG-Link status", base.DEC, LINK_STATUS),
    ec_link_status = ProtoField.uint8("eglink.ec_link_status", "EC-Link status", base.DEC, LINK_STATUS),
    c_link_status = ProtoField.uint8("eglink.c_link_status", "C-Link status", base.DEC, LINK_STATUS),
    armed_ru = ProtoField.uint16("eglink.armed_ru", "Armed RU", base.HEX, nil, nil,
        "Unique ID of the armed RU, 0 when none is armed"),
    ru_state = ProtoField.uint8("eglink.ru_state", "RU state", base.DEC, RU_STATE, nil, "State of the armed RU"),
    ru_battery = ProtoField.uint8("eglink.ru_battery", "RU battery", PERCENT_BASE, UNITS_PERCENT, nil,
        "Battery level of the armed RU (0..100 %)"),
    ru_rssi = ProtoField.uint8("eglink.ru_rssi", "RU C-Link RSSI", PERCENT_BASE, UNITS_PERCENT, nil,
        "C-Link signal level of the armed RU (0..100 %)"),
    ru_cable = ProtoField.uint8("eglink.ru_cable", "RU cable", base.DEC, RU_CABLE, nil,
        "1 when the RU runs on cable, 0 on wireless VisionLink"),
    ru_docked = ProtoField.uint8("eglink.ru_docked", "RU docked", base.DEC, RU_DOCKED, nil,
        "1 when the RU sits in its docking station"),
    ru_disabled = ProtoField.uint8("eglink.ru_disabled", "RU disabled", base.DEC, RU_DISABLED, nil,
        "Why the armed RU's movements are disabled (0 = enabled)"),
    joystick = {},
    switch = {},
    encoder = ProtoField.uint8("eglink.encoder", "Encoder", base.DEC, nil, nil,
        "Encoder value; wraps around as the encoder turns"),
    encoder_switch = ProtoField.uint8("eglink.encoder_switch", "Encoder switch", base.DEC, ENCODER_SWITCH, nil,
        "1 while the encoder is pushed down"),

    packet_number = ProtoField.uint16("eglink.packet_number", "Packet number", base.DEC, nil, nil,
        "Number of this packet within a split periodic output, from 0"),
    periodic_data = ProtoField.bytes("eglink.periodic_data", "Periodic data", base.NONE,
        "Periodic process data from the machine controller to the RU application"),

    command_id = ProtoField.uint16("eglink.command_id", "Command ID", base.DEC, nil, nil,
        "Sequential command number; an acknowledge carries the ID it acknowledges"),
    command_data = ProtoField.bytes("eglink.command_data", "Command data", base.NONE,
        "Command data between the RU application and the machine controller"),
}
for i = 1, 4 do
    pf.joystick[i] = ProtoField.int16("eglink.joystick" .. i, "Joystick " .. i, base.DEC, nil, nil,
        "Position of joystick " .. i .. " (-1000..+1000, 0 = passive)")
end
local SWITCH_BLURB = { "State of switch 1 (leftmost)" }
for i = 1, 8 do
    pf.switch[i] = ProtoField.int16("eglink.switch" .. i, "Switch " .. i, base.DEC, nil, nil,
        SWITCH_BLURB[i] or ("State of switch " .. i))
end

-- In the C plugin's registration order (tshark -G fields lists them so).
local field_list = {
    pf.type, pf.revision, pf.origin, pf.serial, pf.size, pf.spare, pf.payload, pf.payload_spare,
    pf.extra_payload, pf.unknown_payload, pf.crc, pf.crc_status,
    pf.bu_state, pf.relays_open, pf.vlaps, pf.unarmed_rus, pf.eg_link_status, pf.ec_link_status,
    pf.c_link_status, pf.armed_ru, pf.ru_state, pf.ru_battery, pf.ru_rssi, pf.ru_cable, pf.ru_docked,
    pf.ru_disabled,
}
for i = 1, 4 do field_list[#field_list + 1] = pf.joystick[i] end
for i = 1, 8 do field_list[#field_list + 1] = pf.switch[i] end
for _, f in ipairs({ pf.encoder, pf.encoder_switch, pf.packet_number, pf.periodic_data, pf.command_id,
                     pf.command_data }) do
    field_list[#field_list + 1] = f
end
local field_list_own = {}
for i = 1, #field_list do field_list_own[i] = field_list[i] end
if analysis then analysis.fields(field_list) end
-- (what the analysis takes from the dissector through vrshark/eglink_data.luam:
-- hf_eglink_periodic_data, eglink_is_input_port() and eglink_data_dissect() in C)
handoff.periodic_data_field = pf.periodic_data
proto.fields = field_list

-- (the field names, for set_text as proto_registrar_get_name() gives them)
local NAME = {
    bu_state = "BU state", eg_link_status = "EG-Link status", ec_link_status = "EC-Link status",
    c_link_status = "C-Link status", ru_state = "RU state", ru_cable = "RU cable", ru_docked = "RU docked",
    ru_disabled = "RU disabled", encoder_switch = "Encoder switch",
}

------------------------------------------------------------------------
-- Expert infos (the same names, texts, groups and severities as the C plugin)
------------------------------------------------------------------------
local E, G, S = ProtoExpert.new, expert.group, expert.severity
local ei = {
    too_short = E("eglink.too_short", "Packet too short for packet ID, header and CRC", G.MALFORMED, S.ERROR),
    size_mismatch = E("eglink.size.mismatch", "Header Size does not match the UDP payload length - 20",
        G.MALFORMED, S.ERROR),
    size_invalid = E("eglink.size.invalid", "Payload size is wrong for this packet type", G.MALFORMED, S.ERROR),
    type_unknown = E("eglink.type.unknown", "Unknown packet type", G.UNDECODED, S.WARN),
    revision_unknown = E("eglink.revision.unknown", "Unknown revision: only revision 0 is known",
        G.PROTOCOL, S.WARN),
    origin_nonzero = E("eglink.origin.nonzero", "Origin must be 0 in packets from the machine controller",
        G.PROTOCOL, S.WARN),
    origin_zero = E("eglink.origin.zero", "Origin is 0 in a packet from the BU", G.PROTOCOL, S.WARN),
    spare_nonzero = E("eglink.spare.nonzero", "Header spare is not 0", G.PROTOCOL, S.WARN),
    payload_spare_nonzero = E("eglink.payload_spare.nonzero", "Payload spare bytes are not 0", G.PROTOCOL, S.WARN),
    crc_bad = E("eglink.crc.bad", "Bad CRC", G.CHECKSUM, S.ERROR),
    crc_variant = E("eglink.crc.variant", "CRC matches another CRC variant or byte order: set the preference",
        G.CHECKSUM, S.WARN),
    relays_open = E("eglink.bu_state.relays_open", "ES-Link relays open", G.RESPONSE_CODE, S.WARN),
    bu_state_unknown = E("eglink.bu_state.unknown", "BU state is not defined", G.PROTOCOL, S.ERROR),
    link_status_unknown = E("eglink.link_status.unknown", "Link status is not defined (0..6)", G.PROTOCOL, S.ERROR),
    vlaps_range = E("eglink.vlaps.range", "More than 3 VLAPs", G.PROTOCOL, S.ERROR),
    ru_state_stopped = E("eglink.ru_state.stopped", "RU stopped: ES-Link relays open", G.RESPONSE_CODE, S.WARN),
    link_status_passive = E("eglink.link_status.passive", "Link status Passive where TS-0006 does not allow it",
        G.PROTOCOL, S.WARN),
    ru_state_disarmed = E("eglink.ru_state.disarmed", "RU state Disarmed (used inside the BU only)",
        G.PROTOCOL, S.NOTE),
    ru_state_unknown = E("eglink.ru_state.unknown", "RU state is not defined (0..4)", G.PROTOCOL, S.ERROR),
    ru_battery_range = E("eglink.ru_battery.range", "RU battery above 100 %", G.PROTOCOL, S.ERROR),
    ru_rssi_range = E("eglink.ru_rssi.range", "RU C-Link RSSI above 100 %", G.PROTOCOL, S.ERROR),
    flag_invalid = E("eglink.flag.invalid", "Flag is neither 0 nor 1", G.PROTOCOL, S.ERROR),
    ru_disabled_unknown = E("eglink.ru_disabled.unknown", "RU disabled reason is not defined (0..3)",
        G.PROTOCOL, S.ERROR),
    joystick_range = E("eglink.joystick.range", "Joystick position outside -1000..+1000", G.PROTOCOL, S.ERROR),
    unarmed_data = E("eglink.armed_ru.unarmed_data", "No RU is armed but RU fields are not 0", G.PROTOCOL, S.ERROR),
    fields_disagree = E("eglink.fields_disagree", "VRPI fields contradict each other", G.PROTOCOL, S.WARN),
    link_status_fault = E("eglink.link_status.fault", "Link status reports a fault (2..5)", G.RESPONSE_CODE, S.WARN),
    cut = E("eglink.cut", "Packet cut by the capture (snaplen)", G.UNDECODED, S.NOTE),
}
local expert_list = {
    ei.too_short, ei.size_mismatch, ei.size_invalid, ei.type_unknown, ei.revision_unknown, ei.origin_nonzero,
    ei.origin_zero, ei.spare_nonzero, ei.payload_spare_nonzero, ei.crc_bad, ei.crc_variant, ei.relays_open,
    ei.bu_state_unknown, ei.link_status_unknown, ei.vlaps_range, ei.ru_state_stopped, ei.link_status_passive,
    ei.ru_state_disarmed, ei.ru_state_unknown,
    ei.ru_battery_range, ei.ru_rssi_range, ei.flag_invalid, ei.ru_disabled_unknown, ei.joystick_range,
    ei.unarmed_data, ei.fields_disagree, ei.link_status_fault, ei.cut,
}
if analysis then analysis.experts(expert_list) end
proto.experts = expert_list

------------------------------------------------------------------------
-- Preferences (the same names, defaults and values as the C plugin)
------------------------------------------------------------------------
local CRC_MPEG2, CRC_BZIP2, CRC_ISO_HDLC, CRC_STM32 = 0, 1, 2, 3
local CRC_LE, CRC_BE = 0, 1
local CRC_VARIANTS = {
    { "mpeg2", "CRC-32/MPEG-2 (TS-0006)", CRC_MPEG2 },
    { "bzip2", "CRC-32/BZIP2", CRC_BZIP2 },
    { "iso_hdlc", "CRC-32/ISO-HDLC (Ethernet, zlib)", CRC_ISO_HDLC },
    { "stm32", "STM32 hardware CRC (32-bit words)", CRC_STM32 },
}
-- Names as a field engineer reads them in expert info.
local CRC_VARIANT_NAMES = { [0] = "CRC-32/MPEG-2", "CRC-32/BZIP2", "CRC-32/ISO-HDLC", "STM32 hardware CRC" }
local CRC_ORDERS = {
    { "le", "Little-endian (TS-0006)", CRC_LE },
    { "be", "Big-endian", CRC_BE },
}

proto.prefs.input_port = Pref.range("Input UDP port(s)", DEFAULT_INPUT_PORTS,
    "UDP port(s) the BU sends VRPI, VRCI and VRAI to. The machine controller sends "
    .. "VRPO, VRCO and VRAO to the port 2 higher, which is registered as well.", 65535)
proto.prefs.crc_variant = Pref.enum("CRC variant", CRC_MPEG2,
    "CRC algorithm of the trailing CRC. TS-0006 specifies CRC-32/MPEG-2; some firmware "
    .. "computes another variant (the expert info names the one that matches).", CRC_VARIANTS, false)
proto.prefs.crc_byte_order = Pref.enum("CRC byte order", CRC_LE,
    "Byte order of the stored CRC. TS-0006 specifies little-endian.", CRC_ORDERS, false)
proto.prefs.heuristic = Pref.bool("Detect EG-Link on any UDP port", true,
    "Look for EG-Link packets (\"VR\", a known packet type and a matching Size) on UDP "
    .. "ports other than the configured ones.")
if analysis then analysis.prefs(proto) end

local opt = { crc_variant = CRC_MPEG2, crc_order = CRC_LE, heuristic = true, input = {} }

------------------------------------------------------------------------
-- CRC (the C plugin's eglink_crc_compute)
------------------------------------------------------------------------
-- Results as unsigned numbers 0..2^32-1 (the bit library's are signed).
local TWO32 = 4294967296
local function u32(x) return x % TWO32 end

local MPEG2_TABLE, HDLC_TABLE = {}, {}
for i = 0, 255 do
    local c = lshift(i, 24)
    for _ = 1, 8 do
        if band(c, 0x80000000) ~= 0 then c = bxor(lshift(c, 1), 0x04C11DB7) else c = lshift(c, 1) end
    end
    MPEG2_TABLE[i] = c
    local r = i
    for _ = 1, 8 do
        if band(r, 1) ~= 0 then r = bxor(rshift(r, 1), 0xEDB88320) else r = rshift(r, 1) end
    end
    HDLC_TABLE[i] = r
end

-- Sixteen bytes a step (slicing by 16) with sixteen tables of 256 entries:
-- Sk[b] is the CRC, from 0, of the byte b followed by k zero bytes
-- (b * x^(32 + 8k) mod P; S0 is MPEG2_TABLE). Sixteen bytes move the CRC
-- C to S15[x1] ~ S14[x2] ~ S13[x3] ~ S12[x4] ~ S11[b5] ~ ... ~ S0[b16],
-- x1..x4 the bytes of C ~ (b1..b4 as a 32-bit word): one
-- string.byte and two bxor calls a step (a bit library call costs more than
-- the rest of the step; bxor takes any number of arguments), the bytes of x
-- split by arithmetic. Four bytes a step the same way with S3..S0, and
-- the last r < 4 bytes M as (C_top ~ M) * x^32 ~ C_low << 8r. The tables
-- stay small: a big table costs every garbage collection cycle its walk.
local SLICE = { [0] = MPEG2_TABLE }
for k = 1, 15 do
    local prev, cur = SLICE[k - 1], {}
    for b = 0, 255 do
        local v = prev[b]
        cur[b] = bxor(lshift(v, 8), MPEG2_TABLE[rshift(v, 24)])
    end
    SLICE[k] = cur
end
local S0, S1, S2, S3 = SLICE[0], SLICE[1], SLICE[2], SLICE[3]
local S4, S5, S6, S7 = SLICE[4], SLICE[5], SLICE[6], SLICE[7]
local S8, S9, S10, S11 = SLICE[8], SLICE[9], SLICE[10], SLICE[11]
local S12, S13, S14, S15 = SLICE[12], SLICE[13], SLICE[14], SLICE[15]
local TAIL_SHIFT = { 16777216, 65536, 256 }   -- 2^(32 - 8r): where r bytes go in a word

-- The four bytes of a 32-bit word (a bit library result: signed), most
-- significant first.
local function word_bytes(x)
    x = x % TWO32
    local x4 = x % 256
    x = (x - x4) / 256
    local x3 = x % 256
    x = (x - x3) / 256
    local x2 = x % 256
    return (x - x2) / 256, x2, x3, x4
end

local function crc_mpeg2(s, n)
    local crc = -1
    n = n or #s
    local i = 1
    while i + 15 <= n do
        local b1, b2, b3, b4, b5, b6, b7, b8, b9, b10, b11, b12, b13, b14, b15, b16 = byte(s, i, i + 15)
        -- (word_bytes() inline: a Lua call a step costs 1 % of a packet)
        local x = bxor(crc, b1 * 16777216 + b2 * 65536 + b3 * 256 + b4) % TWO32
        local x4 = x % 256
        x = (x - x4) / 256
        local x3 = x % 256
        x = (x - x3) / 256
        local x2 = x % 256
        crc = bxor(S15[(x - x2) / 256], S14[x2], S13[x3], S12[x4], S11[b5], S10[b6], S9[b7], S8[b8],
            S7[b9], S6[b10], S5[b11], S4[b12], S3[b13], S2[b14], S1[b15], S0[b16])
        i = i + 16
    end
    while i + 3 <= n do
        local b1, b2, b3, b4 = byte(s, i, i + 3)
        local x1, x2, x3, x4 = word_bytes(bxor(crc, b1 * 16777216 + b2 * 65536 + b3 * 256 + b4))
        crc = bxor(S3[x1], S2[x2], S1[x3], S0[x4])
        i = i + 4
    end
    local r = n - i + 1
    if r > 0 then
        -- (the word's top r bytes are C_top ~ M, the others C_low)
        local b1, b2, b3 = byte(s, i, n)
        local m = r == 1 and b1 or r == 2 and b1 * 256 + b2 or (b1 * 256 + b2) * 256 + b3
        local x1, x2, x3, x4 = word_bytes(bxor(crc, m * TAIL_SHIFT[r]))
        if r == 1 then
            crc = bxor(S0[x1], ((x2 * 256 + x3) * 256 + x4) * 256)
        elseif r == 2 then
            crc = bxor(S1[x1], S0[x2], (x3 * 256 + x4) * 65536)
        else
            crc = bxor(S2[x1], S1[x2], S0[x3], x4 * 16777216)
        end
    end
    return u32(crc)
end

local function crc_iso_hdlc(s)
    local crc = -1
    for i = 1, #s do
        crc = bxor(rshift(crc, 8), HDLC_TABLE[band(bxor(crc, byte(s, i)), 0xFF)])
    end
    return u32(bxor(crc, -1))
end

-- An STM32 CRC unit fed 32-bit words read from little-endian memory shifts
-- each word in most significant byte first: CRC-32/MPEG-2 over the bytes of
-- every 4-byte group in reverse order, a trailing partial word padded with
-- zero bytes.
local function crc_stm32(s)
    local pad = (4 - #s % 4) % 4
    s = s .. string.rep("\0", pad)
    local words = {}
    for i = 1, #s, 4 do words[#words + 1] = s:sub(i, i + 3):reverse() end
    return crc_mpeg2(table.concat(words))
end

local function crc_compute(s, variant)
    if variant == CRC_BZIP2 then return u32(bxor(crc_mpeg2(s), -1)) end
    if variant == CRC_ISO_HDLC then return crc_iso_hdlc(s) end
    if variant == CRC_STM32 then return crc_stm32(s) end
    return crc_mpeg2(s)
end

------------------------------------------------------------------------
-- Helpers
------------------------------------------------------------------------
-- Expected payload size per type: min, max.
local function type_sizes(ptype)
    if ptype == "VRPI" then return VRPI_LEN, VRPI_LEN end
    if ptype == "VRPO" then return VRPO_MIN_LEN, VRPO_MAX_LEN end
    if ptype == "VRCI" or ptype == "VRCO" then return CMD_LEN, CMD_LEN end
    if ptype == "VRAI" or ptype == "VRAO" then return ACK_LEN, ACK_LEN end
    return 0, math.huge
end

-- The packet ID as Wireshark's format_text() shows bytes (tvb_format_text()
-- in the C plugin), for the two bytes after "VR": printable ASCII as is, C
-- escapes for the usual control characters, octal for the other ones; a
-- UTF-8 sequence (overlong ones too) decoded, a printable character kept and
-- any other as \uXXXX; an incomplete or invalid sequence is one U+FFFD.
-- Printable is GLib's g_unichar_isprint(); of the characters two bytes can
-- hold (up to U+07FF) these are not, besides the C0 and C1 controls:
local NOT_PRINTABLE = {}
for _, r in ipairs({ { 0xAD }, { 0x378, 0x379 }, { 0x380, 0x383 }, { 0x38B }, { 0x38D }, { 0x3A2 }, { 0x530 },
                     { 0x557, 0x558 }, { 0x58B, 0x58C }, { 0x590 }, { 0x5C8, 0x5CF }, { 0x5EB, 0x5EE },
                     { 0x5F5, 0x605 }, { 0x61C }, { 0x6DD }, { 0x70E, 0x70F }, { 0x74B, 0x74C },
                     { 0x7B2, 0x7BF }, { 0x7FB, 0x7FC } }) do
    for c = r[1], r[2] or r[1] do NOT_PRINTABLE[c] = true end
end
local ESCAPES = { [7] = "\\a", [8] = "\\b", [12] = "\\f", [10] = "\\n", [13] = "\\r", [9] = "\\t", [11] = "\\v" }
local REPLACEMENT = "\239\191\189"

-- continuation bytes a UTF-8 lead byte wants (0: no lead byte)
local function utf8_wants(b)
    if b >= 0xC0 and b <= 0xDF then return 1 end
    if b >= 0xE0 and b <= 0xEF then return 2 end
    if b >= 0xF0 and b <= 0xF7 then return 3 end
    if b >= 0xF8 and b <= 0xFB then return 4 end
    if b >= 0xFC and b <= 0xFD then return 5 end
    return 0
end

-- (the payload bits of a lead byte: b % LEAD_MOD[wants])
local LEAD_MOD = { [0] = 64, 32, 16, 8, 4, 2 }

local function utf8_char(c)
    if c < 0x80 then return string.char(c) end
    return string.char(0xC0 + math.floor(c / 64), 0x80 + c % 64)
end

local function format_text(s)
    local out = {}
    local i, n = 1, #s
    while i <= n do
        local b = s:byte(i)
        i = i + 1
        if b >= 0x20 and b < 0x7F then
            out[#out + 1] = string.char(b)
        elseif b < 0x80 then
            out[#out + 1] = ESCAPES[b] or string.format("\\%03o", b)
        else
            local wants = utf8_wants(b)
            local c = b % LEAD_MOD[wants]
            local got = 0
            while wants > 0 and got < wants and i <= n do
                local cb = s:byte(i)
                if cb < 0x80 or cb > 0xBF then break end
                c = c * 64 + cb % 64
                got = got + 1
                i = i + 1
            end
            if wants == 0 or got < wants or c > 0x7FF then
                out[#out + 1] = REPLACEMENT
            elseif (c >= 0x20 and c < 0x7F) or (c >= 0xA0 and not NOT_PRINTABLE[c]) then
                out[#out + 1] = utf8_char(c)
            else
                out[#out + 1] = string.format("\\u%04X", c)
            end
        end
    end
    return table.concat(out)
end

-- " (46 bytes)", what the Payload item appends
local payload_labels = {}
local function payload_label(len)
    local t = payload_labels[len]
    if not t then
        t = string.format(" (%d byte%s)", len, len == 1 and "" or "s")
        if len <= 65535 then payload_labels[len] = t end
    end
    return t
end

local function value_name(value, vals)
    return vals[value] or string.format("Unknown (0x%02x)", value)
end

------------------------------------------------------------------------
-- Sparse display: an invisible tree (the packet list, tshark -Y)
------------------------------------------------------------------------
-- Wireshark throws away every item of an invisible tree whose field nobody
-- references (docs/quality.md, "What the decoders add, and when"). On such
-- a tree the decoder adds only the referenced fields of its own (not the
-- analysis's, not the reassembled periodic data), flat under the protocol
-- item, besides the protocol item, the columns and the expert info (Lua
-- cannot tell whether these are looked at), and the analysis adds no items.
-- `want` is nil for the full tree, else the set of the fields to add,
-- this frame's (what is referenced changes from one dissection to the
-- next in Wireshark; in tshark once a pass). It comes from the view frontends.lua_view() makes from
-- TreeItem:referenced(), as for MC-MB2-PN and EC-Link: nil (the full tree)
-- on a visible tree, without that method, with VRSHARK_FULL_TREE set, or
-- with the protocol referenced with none of its fields; the view of no
-- fields (NOTHING) when nothing of EG-Link is referenced; else the
-- referenced fields, which mean the full tree when one of them is one the
-- decoder cannot add alone. tests/test_eglink_sparse_view.py.
local want
local NOTHING = {}
local sparse_by_name            -- filter name -> ProtoField, the fields the sparse display adds

-- What a view (fields by filter name) means here: NOTHING, the set
-- { [ProtoField] = true }, or false (the full tree).
local function want_of(view)
    if not sparse_by_name then
        local own = {}
        for _, f in ipairs(field_list_own) do
            if f ~= pf.periodic_data then own[f] = true end
        end
        sparse_by_name = {}
        local fields, names = fe.field_names(proto)
        for i = 1, fields and #fields or 0 do
            if own[fields[i]] then sparse_by_name[names[i]] = fields[i] end
        end
    end
    if next(view.fields) == nil then return NOTHING end
    local set = {}
    for name in pairs(view.fields) do
        local f = sparse_by_name[name]
        if not f then return false end
        set[f] = true
    end
    return set
end

local function frame_want(tree, visited)
    local view = fe.lua_view(proto, tree, visited)
    if not view then return nil end
    local w = view.eglink_want
    if w == nil then
        w = want_of(view)
        view.eglink_want = w
    end
    return w or nil
end

local function show_unknown(ti, key, value)
    if want and not want[pf[key]] then return end
    ti:set_text(string.format("%s: Unknown (0x%02x)", NAME[key], value))
end

------------------------------------------------------------------------
-- Payload: p = { tvb, pinfo, tree, base, len, cap, undefined }
------------------------------------------------------------------------
-- (the values are read from p.raw, the packet's bytes in the capture, read
-- once: raw byte i + 1 is tvb offset i)
-- An unsigned little-endian value of 1, 2 or 4 bytes at tvb offset pos.
local function le_uint(raw, pos, len)
    if len == 1 then return byte(raw, pos + 1) end
    if len == 2 then
        local a, b = byte(raw, pos + 1, pos + 2)
        return a + b * 256
    end
    local a, b, c, d = byte(raw, pos + 1, pos + 4)
    return a + b * 256 + c * 65536 + d * 16777216
end

-- Adds an unsigned little-endian payload field if it fits: value, item (nil if not).
local function add_uint(p, field, off, len)
    if off + len > p.cap then return nil end
    local pos = p.base + off
    if want and not want[field] then return le_uint(p.raw, pos, len), p.tree end
    return le_uint(p.raw, pos, len), t_add_le(p.tree, field, tvb_range(p.tvb, pos, len))
end

-- The same for a signed 16-bit field.
local function add_int(p, field, off)
    if off + 2 > p.cap then return nil end
    local pos = p.base + off
    local a, b = byte(p.raw, pos + 1, pos + 2)
    local v = a + b * 256
    if v >= 32768 then v = v - 65536 end
    if want and not want[field] then return v, p.tree end
    return v, t_add_le(p.tree, field, tvb_range(p.tvb, pos, 2))
end

-- Adds a byte block with whatever of it is present and captured: its length, item.
local function add_bytes(p, field, off, len)
    if off >= p.cap then return 0 end
    if off + len > p.cap then len = p.cap - off end
    if len <= 0 then return 0 end
    if want and not want[field] then return len, p.tree end
    return len, t_add(p.tree, field, tvb_range(p.tvb, p.base + off, len))
end

-- A finding on a payload value; none in a packet whose CRC fits no variant,
-- whose values are its corrupted bytes (its CRC finding says so, once).
local function value_finding(p, ti, e, text)
    if not p.untrusted then ti:add_proto_expert_info(e, text) end
end

local function check_payload_spare(p, off, len)
    local present, ti = add_bytes(p, pf.payload_spare, off, len)
    local raw, first = p.raw, p.base + off
    for i = 1, present do
        if byte(raw, first + i) ~= 0 then
            value_finding(p, ti, ei.payload_spare_nonzero,
                "Payload spare bytes are not 0: reserved for future use, the sender "
                .. "may use a newer layout than TS-0006")
            break
        end
    end
end

-- An undefined or out-of-range value: an error in the Protocol group, and
-- the Info tag [undefined].
local function undefined(p, ti, e, text)
    if p.untrusted then return end
    value_finding(p, ti, e, text)
    p.undefined = true
end

-- A 0/1 field (cable, docked, encoder switch) with its value names.
local function check_flag(p, ti, key, name, value)
    if value <= 1 then return end
    show_unknown(ti, key, value)
    undefined(p, ti, ei.flag_invalid, string.format("%s Unknown (0x%02x): only 0 and 1 are defined", name, value))
end

local function check_link_status(p, ti, key, name, value)
    if LINK_STATUS[value] then return end
    show_unknown(ti, key, value)
    undefined(p, ti, ei.link_status_unknown, string.format("%s Unknown (0x%02x): defined are 0..6", name, value))
end

-- TS-0006 4.1.2: Passive (link not in use) is reported on the C-Link only,
-- and only when no remote is armed. i: 1 EG-Link, 2 EC-Link, 3 C-Link.
local LINK_NAMES = { "EG-Link", "EC-Link", "C-Link" }
local function check_passive(p, ti, i, value, armed_ru)
    if not ti or value ~= LINK_PASSIVE then return end
    if i ~= 3 then
        value_finding(p, ti, ei.link_status_passive,
            string.format("%s status Passive: only the C-Link reports Passive", LINK_NAMES[i]))
    elseif armed_ru and armed_ru ~= 0 then
        value_finding(p, ti, ei.link_status_passive, string.format(
            "C-Link status Passive while RU 0x%04x is armed: Passive only when no remote is armed", armed_ru))
    end
end

-- TS-0006 4.1.2: what a link status 2..5 says of a link in use (0 Unused
-- and 6 Passive say it is not in use).
local LINK_FAULT = status_names.LINK_FAULT
local function check_link_fault(p, ti, name, value)
    local why = LINK_FAULT[value]
    if why then
        value_finding(p, ti, ei.link_status_fault,
            string.format("%s %s (%d): %s", name, LINK_STATUS[value], value, why))
    end
end

local BU_STATE_INITIAL, BU_STATE_STOPPED, BU_STATE_LINK_ERROR, BU_STATE_ARMED = 0x00, 0x01, 0x02, 0x11
local RU_STATE_INITIAL, RU_STATE_ARMED, RU_STATE_ENABLED = 0, 2, 3

-- Fields that contradict each other (one warning each, naming both fields
-- and their values): RU state against RU disabled and Armed RU (TS-0006 4.1,
-- 4.1.3), BU state against the armed RU (4.1.1), an EC-Link error while the
-- BU goes on (TS-0007 9: an EC-Link error locks the BU in Initial). f: the
-- values and items, nil where the capture does not hold the field. The same
-- rules and texts as the C plugin and the EC-Link images.
local vrpi_fields = {}   -- check_disagree()'s argument, filled by each VRPI
local function check_disagree(p, f)
    local bu = BU_STATE[f.bu_state] or "Unknown"
    local ru = f.ru_state and (RU_STATE[f.ru_state] or "Unknown")
    local dis = f.ru_disabled and (RU_DISABLED[f.ru_disabled] or "Unknown")
    if f.ru_state and f.ru_disabled then
        if f.ru_state == RU_STATE_ENABLED and f.ru_disabled >= 1 and f.ru_disabled <= 3 then
            value_finding(p, f.disabled_ti, ei.fields_disagree, string.format(
                "RU state %s (%d) but RU disabled %s (%d): an enabled RU is not disabled",
                ru, f.ru_state, dis, f.ru_disabled))
        elseif f.ru_state == RU_STATE_ARMED and f.ru_disabled == 0 then
            value_finding(p, f.disabled_ti, ei.fields_disagree, string.format(
                "RU state %s (%d) but RU disabled %s (%d): Armed means movements are disabled, "
                .. "by tilting or inactivity", ru, f.ru_state, dis, f.ru_disabled))
        end
    end
    if f.armed_ru and f.ru_state and f.armed_ru ~= 0 and f.ru_state == RU_STATE_INITIAL then
        value_finding(p, f.ru_ti, ei.fields_disagree, string.format(
            "Armed RU 0x%04x but RU state %s (%d): Initial means no RU is armed yet", f.armed_ru, ru, f.ru_state))
    end
    if f.armed_ru and f.bu_state == BU_STATE_DISARMED and f.armed_ru ~= 0 then
        value_finding(p, f.bu_ti, ei.fields_disagree, string.format(
            "BU state %s (0x%02x) but Armed RU 0x%04x: a disarmed BU is armed against no RU",
            bu, f.bu_state, f.armed_ru))
    elseif f.armed_ru == 0 and (f.bu_state == BU_STATE_ARMED or f.bu_state == BU_STATE_STOPPED) then
        value_finding(p, f.bu_ti, ei.fields_disagree, string.format(
            "BU state %s (0x%02x) but Armed RU 0: in that state the BU is armed against an RU", bu, f.bu_state))
    end
    if f.ru_state and f.bu_state == BU_STATE_STOPPED
        and (f.ru_state == RU_STATE_ARMED or f.ru_state == RU_STATE_ENABLED) then
        value_finding(p, f.bu_ti, ei.fields_disagree, string.format(
            "BU state %s (0x%02x) but RU state %s (%d): the BU stops when its RU signals stop "
            .. "(RU state Stopped)", bu, f.bu_state, ru, f.ru_state))
    end
    if f.ec_link and LINK_FAULT[f.ec_link] and BU_STATE[f.bu_state]
        and f.bu_state ~= BU_STATE_INITIAL and f.bu_state ~= BU_STATE_LINK_ERROR then
        value_finding(p, f.ec_ti, ei.fields_disagree, string.format(
            "EC-Link status %s (%d) but BU state %s (0x%02x): an EC-Link error holds the BU in Initial",
            LINK_STATUS[f.ec_link], f.ec_link, bu, f.bu_state))
    end
end

local function check_percent(p, ti, e, name, value)
    if value > 100 then undefined(p, ti, e, string.format("%s %d %% is above 100 %%", name, value)) end
end

-- With Armed RU 0 every RU field after it must be 0: name the ones that are not.
local RU_FIELDS = {
    { 8, 1, "RU state" }, { 9, 1, "RU battery" }, { 10, 1, "RU C-Link RSSI" },
    { 11, 1, "RU cable" }, { 12, 1, "RU docked" }, { 13, 1, "RU disabled" },
    { 14, 2, "joystick 1" }, { 16, 2, "joystick 2" }, { 18, 2, "joystick 3" },
    { 20, 2, "joystick 4" }, { 22, 2, "switch 1" }, { 24, 2, "switch 2" },
    { 26, 2, "switch 3" }, { 28, 2, "switch 4" }, { 30, 2, "switch 5" },
    { 32, 2, "switch 6" }, { 34, 2, "switch 7" }, { 36, 2, "switch 8" },
    { 38, 1, "encoder" }, { 39, 1, "encoder switch" },
}
local function check_unarmed(p, armed_ti)
    local names = {}
    for _, f in ipairs(RU_FIELDS) do
        if f[1] + f[2] > p.cap then break end
        if le_uint(p.raw, p.base + f[1], f[2]) ~= 0 then names[#names + 1] = f[3] end
    end
    if #names > 0 then
        undefined(p, armed_ti, ei.unarmed_data,
            "No RU is armed (Armed RU 0) but these RU fields are not 0: " .. table.concat(names, ", "))
    end
end

-- Whether the ES-Link relays are open: below Disarmed, or with the armed RU
-- stopped. known false when the capture cannot tell (RU state cut off by the
-- snap length); a packet without an RU state is judged by its BU state.
local function vrpi_relays(p, bu_state)
    local open = bu_state < BU_STATE_DISARMED
    if open or p.len < 9 then return true, open end
    if p.cap < 9 then return false, open end
    return true, byte(p.raw, p.base + 9) == RU_STATE_STOPPED
end

-- Info of a VRPI names what each value is: "BU=Armed RU 0xbeef=Enabled
-- J1=-1000", the unarmed RUs while the BU is Disarmed, then [relays open].
local info_parts = {}   -- (one table for every VRPI's Info: its first n entries)
local function vrpi_info(p, bu_state, relays_open)
    local have = p.cap
    local parts, n = info_parts, 1
    parts[1] = " BU=" .. value_name(bu_state, BU_STATE)
    if have >= 3 and bu_state == BU_STATE_DISARMED then
        n = n + 1
        parts[n] = " Unarmed RUs=" .. byte(p.raw, p.base + 3)
    end
    if have >= 8 then
        local armed_ru = le_uint(p.raw, p.base + 6, 2)
        local ru_state = have >= 9 and byte(p.raw, p.base + 9) or 0
        if armed_ru ~= 0 or ru_state ~= 0 then
            n = n + 1
            parts[n] = string.format(" RU 0x%04x", armed_ru)
            if have >= 9 then
                n = n + 1
                parts[n] = "=" .. value_name(ru_state, RU_STATE)
            end
        end
    end
    for i = 0, 3 do
        if have < 16 + 2 * i then break end
        local joystick = le_uint(p.raw, p.base + 14 + 2 * i, 2)
        if joystick >= 32768 then joystick = joystick - 65536 end
        if joystick ~= 0 then
            n = n + 1
            parts[n] = string.format(" J%d=%d", i + 1, joystick)
        end
    end
    if relays_open then
        n = n + 1
        parts[n] = " [relays open]"
    end
    col_append(p.cinfo, table.concat(parts, "", 1, n))
end

-- VRPI: BU status and the armed RU's controls.
local function dissect_vrpi(p, info)
    local bu_state, bu_ti = add_uint(p, pf.bu_state, 0, 1)
    if not bu_state then
        col_append(p.cinfo, " (truncated)")
        return
    end
    info.has_bu_state = true
    info.bu_state = bu_state
    local relays_known, relays_open = vrpi_relays(p, bu_state)
    vrpi_info(p, bu_state, relays_known and relays_open)
    if not BU_STATE[bu_state] then
        show_unknown(bu_ti, "bu_state", bu_state)
        undefined(p, bu_ti, ei.bu_state_unknown,
            string.format("BU state Unknown (0x%02x): not defined in TS-0006", bu_state))
    end

    -- ES-Link relays, right below the BU state
    if relays_known and (not want or want[pf.relays_open]) then
        t_set_generated(t_add(p.tree, pf.relays_open, tvb_range(p.tvb, p.base, 1), relays_open))
    end
    if bu_state < BU_STATE_DISARMED then
        value_finding(p, bu_ti, ei.relays_open, string.format("ES-Link relays open: BU state %s (0x%02x), %s",
            BU_STATE[bu_state] or "Unknown", bu_state,
            BU_STATE_ADVICE[bu_state] or "an undefined state below Disarmed"))
    end

    local value, ti = add_uint(p, pf.vlaps, 1, 1)
    if value and value > 3 then
        undefined(p, ti, ei.vlaps_range, string.format("%d VLAPs reported: a BU has at most 3", value))
    end
    add_uint(p, pf.unarmed_rus, 2, 1)
    local eg, eg_ti = add_uint(p, pf.eg_link_status, 3, 1)
    if eg then
        check_link_status(p, eg_ti, "eg_link_status", "EG-Link status", eg)
        check_link_fault(p, eg_ti, "EG-Link status", eg)
    end
    local ec, ec_ti = add_uint(p, pf.ec_link_status, 4, 1)
    if ec then
        check_link_status(p, ec_ti, "ec_link_status", "EC-Link status", ec)
        check_link_fault(p, ec_ti, "EC-Link status", ec)
    end
    local cl, cl_ti = add_uint(p, pf.c_link_status, 5, 1)
    if cl then
        check_link_status(p, cl_ti, "c_link_status", "C-Link status", cl)
        check_link_fault(p, cl_ti, "C-Link status", cl)
    end

    local armed_ru, armed_ti = add_uint(p, pf.armed_ru, 6, 2)
    check_passive(p, eg_ti, 1, eg, armed_ru)
    check_passive(p, ec_ti, 2, ec, armed_ru)
    check_passive(p, cl_ti, 3, cl, armed_ru)
    local ru_state, ru_ti = add_uint(p, pf.ru_state, 8, 1)
    local fields = vrpi_fields   -- (every key set anew for each VRPI: no table a packet)
    fields.bu_state, fields.bu_ti, fields.ec_link, fields.ec_ti = bu_state, bu_ti, ec, ec_ti
    fields.armed_ru, fields.ru_state, fields.ru_ti = armed_ru, ru_state, ru_ti
    if ru_state then
        if ru_state == RU_STATE_STOPPED then
            value_finding(p, ru_ti, ei.ru_state_stopped,
                "RU stopped (stop switch, free-fall/shock sensor or RU fault): ES-Link relays open")
        elseif ru_state == RU_STATE_DISARMED then
            -- TS-0006 4.1.3: Disarmed is used inside the BU only
            value_finding(p, ru_ti, ei.ru_state_disarmed,
                "RU state 1 (Disarmed) on the wire: TS-0006 uses it only inside the BU")
        elseif not RU_STATE[ru_state] then
            show_unknown(ru_ti, "ru_state", ru_state)
            undefined(p, ru_ti, ei.ru_state_unknown,
                string.format("RU state Unknown (0x%02x): defined are 0..4", ru_state))
        end
    end

    value, ti = add_uint(p, pf.ru_battery, 9, 1)
    if value then check_percent(p, ti, ei.ru_battery_range, "RU battery", value) end
    value, ti = add_uint(p, pf.ru_rssi, 10, 1)
    if value then check_percent(p, ti, ei.ru_rssi_range, "RU C-Link RSSI", value) end
    value, ti = add_uint(p, pf.ru_cable, 11, 1)
    if value then check_flag(p, ti, "ru_cable", "RU cable", value) end
    value, ti = add_uint(p, pf.ru_docked, 12, 1)
    if value then check_flag(p, ti, "ru_docked", "RU docked", value) end
    value, ti = add_uint(p, pf.ru_disabled, 13, 1)
    fields.ru_disabled, fields.disabled_ti = value, ti
    if value and not RU_DISABLED[value] then
        show_unknown(ti, "ru_disabled", value)
        undefined(p, ti, ei.ru_disabled_unknown, string.format(
            "RU disabled reason Unknown (0x%02x): defined are 0 enabled, 1 tilted, 2 inactivity, 3 other", value))
    end

    for i = 1, 4 do
        local svalue
        svalue, ti = add_int(p, pf.joystick[i], 14 + 2 * (i - 1))
        if not svalue then break end
        if svalue < -JOYSTICK_LIMIT or svalue > JOYSTICK_LIMIT then
            undefined(p, ti, ei.joystick_range,
                string.format("Joystick %d position %d is outside -1000..+1000", i, svalue))
        end
    end
    for i = 1, 8 do
        if not add_int(p, pf.switch[i], 22 + 2 * (i - 1)) then break end
    end
    add_uint(p, pf.encoder, 38, 1)
    value, ti = add_uint(p, pf.encoder_switch, 39, 1)
    if value then check_flag(p, ti, "encoder_switch", "Encoder switch", value) end
    check_payload_spare(p, 40, 6)

    if armed_ru == 0 then check_unarmed(p, armed_ti) end
    check_disagree(p, fields)

    if p.undefined then col_append(p.cinfo, " [undefined]") end
end

-- VRPO: one fragment of the controller's periodic data.
local function dissect_vrpo(p, info)
    local pkt = add_uint(p, pf.packet_number, 0, 2)
    if not pkt then
        col_append(p.cinfo, " (truncated)")
        return
    end
    -- Of a cut packet, the data the capture holds; the burst is tracked by
    -- the length in the packet.
    add_bytes(p, pf.periodic_data, 2, p.len - 2)
    local data_len = math.max(0, p.len - 2)
    info.has_packet_number = true
    info.packet_number = pkt
    info.periodic_offset = p.base + 2
    info.periodic_len = data_len
    col_append(p.cinfo, string.format(" Pkt=%d %d bytes", pkt, data_len))
end

-- VRCI/VRCO (with_data) and VRAI/VRAO: command ID first.
local function dissect_command(p, info, with_data)
    local cmd = add_uint(p, pf.command_id, 0, 2)
    if not cmd then
        col_append(p.cinfo, " (truncated)")
        return
    end
    info.has_command_id = true
    info.command_id = cmd
    col_append(p.cinfo, " Cmd=" .. cmd)
    if with_data then
        check_payload_spare(p, 2, 4)
        if add_bytes(p, pf.command_data, 6, 16) == 16 then
            handoff.dissect(p.tvb, p.pinfo, p.tree, info.type == "VRCI" and "vrci" or "vrco", info.origin, 0,
                p.base + 6, 16)
        end
    end
end

-- The checksum status as proto_tree_add_checksum() adds it: generated, no
-- length, "CRC status: Good" (a Lua field with base.NONE is shown "Good (1)").
local function add_crc_status(tree, tvb, crc_offset, status)
    if want and not want[pf.crc_status] then return end
    local ti = t_add(tree, pf.crc_status, tvb_range(tvb, crc_offset, 0), status)
    t_set_text(ti, "CRC status: " .. CHECKSUM_STATUS[status])
    t_set_generated(ti)
end

-- The CRC check of one packet (as eglink_crc_check() in C): with the
-- configured variant and byte order, and when that fails, the first other
-- variant and byte order that fits. raw: the packet's bytes, the CRC's included.
local CRC_OK = { ok = true }
local function crc_check(raw, crc_offset)
    local variant, order = opt.crc_variant, opt.crc_order
    local b0, b1, b2, b3 = byte(raw, crc_offset + 1, crc_offset + 4)
    local stored_le = ((b3 * 256 + b2) * 256 + b1) * 256 + b0
    local stored_be = ((b0 * 256 + b1) * 256 + b2) * 256 + b3
    local stored = order == CRC_BE and stored_be or stored_le
    if variant == CRC_MPEG2 and stored == crc_mpeg2(raw, crc_offset) then return CRC_OK end
    local s = sub(raw, 1, crc_offset)
    local computed = { [variant] = crc_compute(s, variant) }
    if stored == computed[variant] then return CRC_OK end
    local c = { ok = false, computed = computed[variant] }
    for v = CRC_MPEG2, CRC_STM32 do
        if v ~= variant then computed[v] = crc_compute(s, v) end
        if computed[v] == stored_le and (v ~= variant or order ~= CRC_LE) then
            c.match, c.order = v, "le"
            break
        end
        if computed[v] == stored_be and (v ~= variant or order ~= CRC_BE) then
            c.match, c.order = v, "be"
            break
        end
    end
    return c
end

-- CRC: the check's result; on failure which variant fits, or that the
-- packet's values are not trusted (said once, instead of a finding per
-- value its corrupted bytes make undefined).
local function dissect_crc(tvb, pinfo, tree, crc_offset, c)
    local shown = not want or want[pf.crc]
    local ti = tree
    if shown then
        local range = tvb_range(tvb, crc_offset, CRC_LEN)
        ti = opt.crc_order == CRC_BE and t_add(tree, pf.crc, range) or t_add_le(tree, pf.crc, range)
    end
    if c.ok then
        if shown then t_append(ti, " [correct]") end
        add_crc_status(tree, tvb, crc_offset, CHECKSUM_GOOD)
        return true
    end
    add_crc_status(tree, tvb, crc_offset, CHECKSUM_BAD)
    if shown then ti:append_text(string.format(" incorrect, should be 0x%08x", c.computed)) end
    col_append(pinfo.cols.info, " [bad CRC]")
    if not c.match then
        ti:add_proto_expert_info(ei.crc_bad, string.format(
            "Bad CRC [should be 0x%08x]: no CRC variant fits, the packet is corrupted: its payload "
            .. "values are not trusted, none is judged", c.computed))
        return false
    end
    ti:add_proto_expert_info(ei.crc_bad, string.format("Bad CRC [should be 0x%08x]", c.computed))
    ti:add_proto_expert_info(ei.crc_variant, string.format(
        "CRC matches %s, %s-endian: set the preference (eglink.crc_variant: %s, eglink.crc_byte_order: %s)",
        CRC_VARIANT_NAMES[c.match], c.order == "be" and "big" or "little", CRC_VARIANTS[c.match + 1][1],
        c.order))
    return false
end

-- Adds a header field if the packet, and the capture, are long enough for it
-- (have: the smaller of the two lengths): value, item.
local function add_header_uint(tree, tvb, raw, field, off, len, have)
    if off + len > have then return nil end
    if want and not want[field] then return le_uint(raw, off, len), tree end
    return le_uint(raw, off, len), t_add_le(tree, field, tvb_range(tvb, off, len))
end

local function analyse(tvb, pinfo, tree, item, info)
    if analysis then analysis.dissect(tvb, pinfo, tree, item, info, want ~= nil) end
end

-- A packet cut by the capture: the C plugin ends it as Wireshark ends every
-- such packet (an exception that shows "[Packet size limited during
-- capture]"); a Lua dissector cannot raise that exception, so it writes the
-- same Info.
local function end_of_capture(cinfo, captured, reported)
    if captured < reported then col_append(cinfo, "[Packet size limited during capture]") end
end

-- The packet ID as the Info column and the item show it, per 4 bytes (or fewer).
local id_texts = {}
local function id_text(s)
    local t = id_texts[s]
    if not t then
        t = format_text(s)
        id_texts[s] = t
    end
    return t
end

local packet_info, payload_ctx = {}, {}
local function dissect(tvb, pinfo, tree)
    local reported, captured = tvb_reported_len(tvb), tvb_len(tvb)
    local have = math.min(reported, captured)   -- bytes in the packet and in the capture
    if captured < 2 then return 0 end
    local raw = tvb_raw(tvb, 0, have)
    if sub(raw, 1, 2) ~= "VR" then return 0 end
    want = frame_want(tree, p_visited(pinfo))

    -- (one info table, every key set anew a packet: nobody keeps it)
    local info = packet_info
    info.type, info.revision, info.origin, info.serial, info.has_serial = "UNKNOWN", 0, 0, 0, false
    info.size, info.size_ok, info.crc_ok, info.cut = 0, false, false, false
    info.has_bu_state, info.bu_state, info.has_command_id, info.command_id = false, 0, false, 0
    info.has_packet_number, info.packet_number, info.periodic_offset, info.periodic_len = false, 0, 0, 0

    local cols = pinfo.cols
    cols.protocol = "EG-Link"
    local cinfo = cols.info
    col_clear(cinfo)

    local eglink_item = t_add(tree, proto, tvb_range(tvb))
    local eglink_tree = eglink_item

    local id4 = have >= 4 and sub(raw, 1, 4) or raw
    local id = id_text(id4)
    col_set(cinfo, id)
    -- (the item's text only where it is seen: not on a sparse tree)
    if not want then t_append(eglink_item, ", " .. id) end
    if have >= 4 then
        info.type = TYPE_OF_ID[id4] or "UNKNOWN"
    end
    if have >= 4 and (not want or want[pf.type]) then
        local ti = t_add(eglink_tree, pf.type, tvb_range(tvb, 0, 4))
        t_append(ti, TYPE_LABEL[info.type])
    end
    if info.type == "UNKNOWN" and (have >= 4 or reported < 4) then
        col_append(cinfo, " (unknown type)")
        eglink_item:add_proto_expert_info(ei.type_unknown,
            "Unknown packet type " .. id .. ": TS-0006 defines VRPI, VRPO, VRCI, VRCO, VRAI and VRAO; "
            .. "only the header and CRC are decoded")
    end

    -- Header
    local value, ti = add_header_uint(eglink_tree, tvb, raw, pf.revision, 4, 2, have)
    if value then
        info.revision = value
        if value ~= 0 then
            ti:add_proto_expert_info(ei.revision_unknown, string.format(
                "Revision %d: only revision 0 (the TS-0006 layout) is known, the payload may differ", value))
        end
    end
    value, ti = add_header_uint(eglink_tree, tvb, raw, pf.origin, 6, 2, have)
    if value then
        info.origin = value
        if info.type ~= "UNKNOWN" and not IS_INPUT[info.type] and value ~= 0 then
            ti:add_proto_expert_info(ei.origin_nonzero, string.format(
                "Origin is 0x%04x in a %s from the machine controller: it must be 0", value, id))
        elseif IS_INPUT[info.type] and value == 0 then
            ti:add_proto_expert_info(ei.origin_zero,
                "Origin is 0 in a " .. id .. " from the BU: the BU should send its unique ID")
        end
    end
    value = add_header_uint(eglink_tree, tvb, raw, pf.serial, 8, 2, have)
    if value then
        info.serial = value
        info.has_serial = true
        if not want then t_append(eglink_item, ", Serial " .. value) end
    end
    local size_ti
    value, size_ti = add_header_uint(eglink_tree, tvb, raw, pf.size, 10, 2, have)
    if value then info.size = value end
    value, ti = add_header_uint(eglink_tree, tvb, raw, pf.spare, 12, 4, have)
    if value and value ~= 0 then
        ti:add_proto_expert_info(ei.spare_nonzero, string.format(
            "Header spare is 0x%08x, not 0: reserved for future use, the sender may use a "
            .. "newer layout than TS-0006", value))
    end

    -- Cut by the capture (snap length): said once, then decoded and analysed
    -- from what it holds, never from bytes it does not hold.
    info.cut = captured < reported
    if info.cut then
        eglink_item:add_proto_expert_info(ei.cut, string.format(
            "Packet cut by the capture (snaplen): %d of %d bytes captured; decoded as far as "
            .. "captured, CRC not checked, counted as received", captured, reported))
        if reported < MIN_LEN or info.type == "UNKNOWN" or not info.has_serial then
            info.cut = false   -- too little of it to analyse: as before
        end
    end
    if have < 4 and reported >= 4 then
        -- not even the packet ID in the capture: nothing to decode
        end_of_capture(cinfo, captured, reported)
        return reported
    end

    if reported < MIN_LEN then
        eglink_item:add_proto_expert_info(ei.too_short, string.format(
            "Packet is %d bytes, too short for packet ID, header and CRC (20 bytes)", reported))
        col_append(cinfo, " (too short)")
        analyse(tvb, pinfo, eglink_tree, eglink_item, info)
        end_of_capture(cinfo, captured, reported)
        return reported
    end

    -- Payload: everything between the header and the CRC at the end of the datagram.
    local p = payload_ctx   -- (as info: every key set anew)
    p.tvb, p.raw, p.pinfo, p.cinfo, p.base, p.len = tvb, raw, pinfo, cinfo, HEADER_LEN, reported - MIN_LEN
    p.undefined, p.tree = false, nil
    p.cap = math.max(0, math.min(p.len, captured - HEADER_LEN))
    -- (checked before the payload: a corrupted packet's values are not judged)
    local crc = captured >= reported and crc_check(raw, reported - CRC_LEN) or nil
    p.untrusted = crc ~= nil and not crc.ok and not crc.match
    info.size_ok = true
    -- (the C plugin files these under the Size item; with the Size not
    -- captured, under no item: only the expert list has them. The nearest
    -- a Lua dissector comes is the frame's top tree.)
    local size_item = size_ti or tree
    if info.size ~= p.len then
        info.size_ok = false
        size_item:add_proto_expert_info(ei.size_mismatch, string.format(
            "Size says %d payload bytes but the UDP payload carries %d (UDP payload length - 20)", info.size, p.len))
    end
    local min_len, max_len = type_sizes(info.type)
    if p.len < min_len or p.len > max_len then
        info.size_ok = false
        if min_len == max_len then
            size_item:add_proto_expert_info(ei.size_invalid, string.format(
                "A %s payload is %d bytes, this one has %d: decoded as far as it goes", id, min_len, p.len))
        else
            size_item:add_proto_expert_info(ei.size_invalid, string.format(
                "A %s payload is %d to %d bytes (packet number + up to 488 bytes of data), "
                .. "this one has %d: decoded as far as it goes", id, min_len, max_len, p.len))
        end
    end

    -- (of a cut packet, the item covers what the capture holds)
    if captured >= p.base and (not want or want[pf.payload]) then
        local pti = t_add(eglink_tree, pf.payload, tvb_range(tvb, p.base, math.min(p.len, p.cap)))
        t_append(pti, payload_label(p.len))
        p.tree = pti
    else
        p.tree = eglink_tree
    end
    local ptype = info.type
    if ptype == "VRPI" then
        dissect_vrpi(p, info)
    elseif ptype == "VRPO" then
        dissect_vrpo(p, info)
    elseif ptype == "VRCI" or ptype == "VRCO" then
        dissect_command(p, info, true)
    elseif ptype == "VRAI" or ptype == "VRAO" then
        dissect_command(p, info, false)
    else
        add_bytes(p, pf.unknown_payload, 0, p.len)
        col_append(cinfo, string.format(" %d bytes", p.len))
    end
    if ptype ~= "UNKNOWN" and p.len > max_len then
        add_bytes(p, pf.extra_payload, max_len, p.len - max_len)
    end

    if captured >= reported then
        info.crc_ok = dissect_crc(tvb, pinfo, eglink_tree, reported - CRC_LEN, crc)
    else
        info.crc_ok = info.cut   -- not checked: counted as received when analysable
    end

    analyse(tvb, pinfo, eglink_tree, eglink_item, info)
    end_of_capture(cinfo, captured, reported)
    return reported
end

function proto.dissector(tvb, pinfo, tree)
    return dissect(tvb, pinfo, tree)
end

-- Heuristic: "VR", a defined type, and a Size that matches the datagram.
local function heuristic(tvb, pinfo, tree)
    if not opt.heuristic then return false end
    local reported = tvb:reported_len()
    if tvb:len() < HEADER_LEN or reported < MIN_LEN then return false end
    local head = tvb_raw(tvb, 0, 12)
    if sub(head, 1, 2) ~= "VR" then return false end
    local ptype = TYPE_OF_ID[sub(head, 1, 4)]
    if not ptype then return false end
    local payload_len = reported - MIN_LEN
    if le_uint(head, 10, 2) ~= payload_len then return false end
    local min_len, max_len = type_sizes(ptype)
    if payload_len < min_len or payload_len > max_len then return false end
    dissect(tvb, pinfo, tree)
    return true
end

------------------------------------------------------------------------
-- Ports: the input ports and the output ports (input + 2) on udp.port
------------------------------------------------------------------------
local udp_port = DissectorTable.get("udp.port")
local registered_ports -- the range string registered, or nil

-- "5825,6000-6001" -> { {5825, 5825}, {6000, 6001} }
local function parse_ranges(text)
    local out = {}
    for part in tostring(text or ""):gmatch("[^,%s]+") do
        local low, high = part:match("^(%d+)%-(%d+)$")
        if not low then low = part:match("^(%d+)$") high = low end
        low, high = tonumber(low), tonumber(high)
        if low and high and low <= high and high <= 65535 then out[#out + 1] = { low, high } end
    end
    return out
end

local function register_ports()
    if registered_ports then udp_port:remove(registered_ports, proto) end
    local parts = {}
    for _, r in ipairs(opt.input) do
        parts[#parts + 1] = r[1] .. "-" .. r[2]
        if r[1] + OUTPUT_PORT_OFFSET <= 65535 then
            parts[#parts + 1] = (r[1] + OUTPUT_PORT_OFFSET) .. "-" .. math.min(r[2] + OUTPUT_PORT_OFFSET, 65535)
        end
    end
    registered_ports = #parts > 0 and table.concat(parts, ",") or nil
    if registered_ports then udp_port:add(registered_ports, proto) end
end

-- Whether a UDP port is one of the input ports of the preference (the BU
-- sends to it; the controller sends to it + 2): eglink_is_input_port(), for
-- the analysis (vrshark/eglink_data.luam).
function handoff.is_input_port(port)
    for _, r in ipairs(opt.input) do
        if port >= r[1] and port <= r[2] then return true end
    end
    return false
end

local function prefs_changed()
    opt.crc_variant = proto.prefs.crc_variant
    opt.crc_order = proto.prefs.crc_byte_order
    opt.heuristic = proto.prefs.heuristic
    opt.input = parse_ranges(proto.prefs.input_port)
    register_ports()
    if analysis then analysis.prefs_changed(proto) end
end
proto.prefs_changed = prefs_changed

function proto.init()
    if analysis then analysis.init() end
end

handoff.table = DissectorTable.new(EGLINK_DATA_TABLE, "EG-Link application data", ftypes.STRING, base.NONE, proto)
udp_port:add_for_decode_as(proto)
proto:register_heuristic("udp", heuristic)
prefs_changed()
