--[[ eclink_modbus.lua -- EC-Link process images carried over Modbus/TCP.

The BU is a Modbus/TCP server (port 502). This plugin takes the Modbus/TCP
port from the built-in "mbtcp" dissector, calls it unchanged (its tree stays
as it is) and then adds the EC-Link view of every register and bit access:

  Modbus table          addresses    image                       function codes
  input registers       0..31        input image bytes 0..63     4
  holding registers     2048..2079   input image bytes 0..63     3, 6, 16, 23
  holding registers     0..111       output image bytes 0..223   3, 6, 16, 23
  discrete inputs       0..511       input image bits            2
  coils                 0..1791      output image bits           1, 5, 15
  (bit k = bit k mod 8 of image byte k div 8; register n = image bytes 2n and
   2n+1 with byte 2n in its LOW 8 bits, so every byte pair is swapped on the
   wire; the "swap" preference turns that off)

  MBAP header: transaction id (2), protocol id (2, = 0), length (2), unit (1),
  then the PDU: function code (1) and its data. A response takes its start
  address from its request (paired by connection + transaction + unit +
  function code).

Detection (preference): "heuristic" accepts a connection on evidence only
a BU and its controller give, over time (vrshark/modbus_detect.luam: input
images whose PCI moves at the BU's 125 ms cadence while the other fields
stay, and output writes consistent over more than one write). From the
first image it looks at, the connection is analysed as if accepted; its
frames are shown once it is accepted: the accepting frame and later ones in
one pass, the earlier ones too on a second pass (tshark -2, GUI). A
connection not accepted within CANDIDATE_TRIES ADUs is left to Modbus. An
accepted connection whose input images stop being valid (DROP_IMAGES in a
row) is dropped again with a note, and judged afresh.
"always" decodes every connection on the port; "off" leaves Modbus alone
but for the listed servers.

Servers (preference eclink_modbus.servers, vrshark/modbus_servers.luam):
the BUs the user names are decoded from their first frame, whatever the
detection (an excerpt too short for the evidence); the other servers are
judged as the detection says. A connection the heuristic has not accepted
whose ADU has a BU's shape (modbus_detect.luam) gets the note
eclink_modbus.candidate on that ADU, saying what the evidence still lacks
and the setting that decodes it now (eclink_modbus.candidate_setting); not
on a second pass once the connection was accepted later.

Ports: every port of eclink_modbus.port (a range preference, "502" by
default, e.g. "502,5020") and the port of Wireshark's Modbus/TCP dissector,
mbtcp.tcp.port (502 unless set): either setting adds a port, neither takes
one away (vrshark/modbus_ports.luam), and every hint names the ports already
decoded with the new one. Wireshark's Modbus/TCP dissector tells queries
from responses by its own port, so on another port the BU's port is
presented to it as that one while it runs, and on its own port it is left
alone.
The ports are taken, and mbtcp called, by the transport
(vrshark/transport.luam): the C front end with the C plugin, Lua without
it; the decoder is the same either way and never asks which.

Per connection, on the first pass, the latest value of every image byte is
kept (so each frame can show the assembled images as of that frame), the
handshake is analysed (PCI/PCO stalls, CCI -> CAO and CCO -> CAI echoes,
BU state changes: vrshark/eclink_handshake.lua, shared with EC-Link over
PROFINET) and multiplexed periodic output blocks are reassembled.
Everything is stored per frame, so a second pass and random access show
the same.
]]

local dir = debug.getinfo(1, "S").source:match("^@(.*)[/\\]")
package.path = dir .. "/?.luam;" .. package.path
set_plugin_info(require("vrshark.version").info("EC-Link images in Modbus/TCP (VisionRemote VM-110/VX-100 base units)"))
local image = require("vrshark.eclink_image")
local periodic = require("vrshark.eclink_periodic")
local handshake = require("vrshark.eclink_handshake")
local fe = require("vrshark.frontends")
-- (the names and limits shared with the C front end, taken at load)
local seam = require("vrshark.seam")
local append_info = fe.append_info
local detect = require("vrshark.modbus_detect")
local servers = require("vrshark.modbus_servers")
local ports = require("vrshark.modbus_ports")
local record = require("vrshark.pnio_record") -- add_time(): times to the ms, as over PROFINET
local iodata = require("vrshark.iodata") -- vrshark_io hook
-- the shared clock of streams that stop (TS-0007 8.3, 8.4: the images themselves)
local deadlines = require("vrshark.deadlines")
-- (methods called as functions on the per-frame paths: vrshark/api.luam says why)
local api = require("vrshark.api")
local add, set_generated, append_text, tvb_len, tvb_raw = api.add, api.set_generated, api.append_text, api.len, api.raw
-- (the pinfo attributes read on every frame)
local p_number, p_visited, p_abs_ts, p_src, p_dst = api.pinfo.number, api.pinfo.visited, api.pinfo.abs_ts,
    api.pinfo.src, api.pinfo.dst
local p_match_uint = api.pinfo.match_uint
local tvb_reported_len = api.reported_len
-- (the flat records by frame number: vrshark/framemap.luam says why)
local framemap = require("vrshark.framemap")
local passes = require("vrshark.passes")
local health = require("vrshark.health") -- Statistics > EC-Link
local fget, fset = framemap.get, framemap.set

image.proto()  -- the single Proto("eclink"), shared with the other EC-Link plugins
local proto = Proto("eclink_modbus", "EC-Link over Modbus/TCP")
-- the Protos of its fields (frontends.lua_view())
local LUA_PROTOS = { proto, image.proto() }
-- Its transport (vrshark/transport.luam): the C front end or, without the
-- C plugin, mbtcp wrapped in Lua; chosen once, when the module loads. The
-- decoder's entry point, dissect() below, is the same for both.
local transport = require("vrshark.transport").modbus(proto, LUA_PROTOS)
local lua_view = transport.lua_view

------------------------------------------------------------------------
-- Fields
------------------------------------------------------------------------
local pf = {
    table = ProtoField.string("eclink_modbus.table", "Modbus table"),
    request_in = ProtoField.framenum("eclink_modbus.request_in", "Request in", base.NONE, frametype.REQUEST),
    response_in = ProtoField.framenum("eclink_modbus.response_in", "Response in", base.NONE, frametype.RESPONSE),
    time = ProtoField.relative_time("eclink_modbus.time", "Time since request"),
    accepted_in = ProtoField.framenum("eclink_modbus.accepted_in", "Connection recognized in"),
    server = ProtoField.string("eclink_modbus.server", "BU (Modbus/TCP server)"),
    bits = ProtoField.string("eclink_modbus.bits", "Partial image byte"),
    assembled = ProtoField.string("eclink_modbus.assembled", "Assembled image"),
    pci_age = ProtoField.relative_time("eclink_modbus.pci_age", "Time since PCI changed"),
    pco_age = ProtoField.relative_time("eclink_modbus.pco_age", "Time since PCO changed"),
    pci_age_ms = ProtoField.uint32("eclink_modbus.pci_age_ms", "Time since PCI changed (ms)"),
    pco_age_ms = ProtoField.uint32("eclink_modbus.pco_age_ms", "Time since PCO changed (ms)"),
    bu_state_prev = ProtoField.uint8("eclink_modbus.bu_state_prev", "Previous BU state", base.HEX,
        image.vs.bu_state),
    cmd_from_ru_in = ProtoField.framenum("eclink_modbus.cmd_from_ru_in", "Command from RU (new CCI) in",
        base.NONE, frametype.REQUEST),
    cao_in = ProtoField.framenum("eclink_modbus.cao_in", "Acknowledged by CAO in", base.NONE, frametype.ACK),
    cmd_from_ru_latency = ProtoField.relative_time("eclink_modbus.cmd_from_ru_latency",
        "Command from RU acknowledge time"),
    cmd_to_ru_in = ProtoField.framenum("eclink_modbus.cmd_to_ru_in", "Command to RU (new CCO) in",
        base.NONE, frametype.REQUEST),
    cai_in = ProtoField.framenum("eclink_modbus.cai_in", "Acknowledged by CAI in", base.NONE, frametype.ACK),
    cmd_to_ru_latency = ProtoField.relative_time("eclink_modbus.cmd_to_ru_latency",
        "Command to RU acknowledge time"),
    periodic_reassembled_in = ProtoField.framenum("eclink_modbus.periodic.reassembled_in",
        "Periodic data reassembled in"),
    periodic_block_in = ProtoField.framenum("eclink_modbus.periodic.block_in", "Periodic data block in"),
    periodic_length = ProtoField.uint32("eclink_modbus.periodic.length", "Reassembled periodic data length"),
    periodic_data = ProtoField.bytes("eclink_modbus.periodic.data", "Reassembled periodic data"),
    poll_gap_time = ProtoField.relative_time("eclink_modbus.poll_gap_time", "Time since the previous input image read"),
    poll_gap_from = ProtoField.framenum("eclink_modbus.poll_gap_from", "Previous input image read in"),
    candidate_setting = ProtoField.string("eclink_modbus.candidate_setting", "Setting that decodes this server"),
    missing_since = ProtoField.framenum("eclink_modbus.missing_since", "Image's last frame"),
    missing_time = ProtoField.relative_time("eclink_modbus.missing_time", "Time since the image's last frame"),
    closed_in = ProtoField.framenum("eclink_modbus.closed_in", "TCP connection ended in"),
}
-- frame links of the handshake findings (PCI/PCO unchanged since, command in)
local hs_fields, hs_new_fields = handshake.fields("eclink_modbus", pf)
local pf_list = {}
for _, f in pairs(pf) do pf_list[#pf_list + 1] = f end
for _, f in ipairs(hs_new_fields) do pf_list[#pf_list + 1] = f end
pf.pci_since, pf.pco_since, pf.deadline_in = hs_fields.pci_since, hs_fields.pco_since, hs_fields.deadline_in
proto.fields = pf_list

-- the handshake experts (same wording as over PROFINET) come from vrshark.eclink_handshake
local ef, hs_experts = handshake.experts("eclink_modbus")
ef.periodic_reassembled = ProtoExpert.new("eclink_modbus.periodic.reassembled", "Periodic data reassembled",
    expert.group.REASSEMBLE, expert.severity.CHAT)
ef.no_request = ProtoExpert.new("eclink_modbus.no_request", "Response without a request in the capture",
    expert.group.SEQUENCE, expert.severity.NOTE)
-- a controller that does not read the input image cannot watch PCI
ef.poll_gap = ProtoExpert.new("eclink_modbus.poll_gap", "Input image not read for longer than the PCI timeout",
    expert.group.SEQUENCE, expert.severity.WARN)
-- an accepted connection whose input images stopped being a BU's
ef.dropped = ProtoExpert.new("eclink_modbus.dropped", "Input images no longer valid: not taken for a BU any more",
    expert.group.PROTOCOL, expert.severity.NOTE)
-- a connection with a BU's shape the heuristic has not accepted (yet): never silent
ef.candidate = ProtoExpert.new("eclink_modbus.candidate",
    "Looks like a BU's Modbus/TCP server, not recognised: the setting that decodes it",
    expert.group.UNDECODED, expert.severity.NOTE)
hs_experts[#hs_experts + 1] = ef.periodic_reassembled
hs_experts[#hs_experts + 1] = ef.candidate
hs_experts[#hs_experts + 1] = ef.dropped
hs_experts[#hs_experts + 1] = ef.no_request
-- TCP data of a decoded connection that does not start an ADU: what TCP hands
-- over after segments out of order (either direction), never silent
ef.mid_adu = ProtoExpert.new("eclink_modbus.mid_adu", "TCP data from inside an ADU, not decoded",
    expert.group.SEQUENCE, expert.severity.NOTE)
hs_experts[#hs_experts + 1] = ef.mid_adu
-- A request Wireshark's TCP did not hand over, most often because its
-- segments came out of order: TCP reassembles those only when told to.
local NO_REQUEST_TEXT = "Response without a request in the capture: the request was not captured, or its TCP "
    .. "segments came out of order (TCP Previous segment not captured, Retransmission), which "
    .. "tcp.reassemble_out_of_order:TRUE reassembles"
-- (under the 240 characters of an expert message, whatever the size)
local MID_ADU_TEXT = "TCP data from inside an ADU, not decoded (%d bytes from the %s): earlier segments not captured, "
    .. "or out of order (TCP Previous segment not captured, Retransmission), which "
    .. "tcp.reassemble_out_of_order:TRUE reassembles"
hs_experts[#hs_experts + 1] = ef.poll_gap
-- a BU's image stream that stopped: no read of the input image within the
-- PCI timeout (TS-0007 8.3), no write of the output image within 2000 ms
-- (8.4), said on the first frame after the deadline whatever carries it; and
-- the PLC's TCP connection to a BU that ended (the images' stall, if any,
-- is said by the first two)
for _, e in ipairs({
    { "input_missing", "BU's input image not read within the PCI timeout", "ERROR" },
    { "output_missing", "BU's output image not written within 2000 ms", "ERROR" },
    { "connection_closed", "TCP connection to a BU closed (FIN)", "WARN" },
    { "connection_reset", "TCP connection to a BU reset (RST)", "WARN" },
}) do
    ef[e[1]] = ProtoExpert.new("eclink_modbus." .. e[1], e[2], expert.group.SEQUENCE, expert.severity[e[3]])
    hs_experts[#hs_experts + 1] = ef[e[1]]
end
proto.experts = hs_experts
-- Statistics > EC-Link, tshark -z eclink,stat: EC-Link over Modbus/TCP and PROFINET (vrshark/health.luam)
require("vrshark.health").register("eclink", "EC-Link", "eclink,stat")
-- the BU display text beside the findings that cause it (TS-0007 9): eclink.lcd
local LCD = handshake.lcd_by_expert(ef)

------------------------------------------------------------------------
-- Value tables
------------------------------------------------------------------------
-- Modbus tables and where they sit in the images: { kind, first address,
-- last address }, at the addresses of the seam contract (a BU's evidence:
-- the C front end reads the same)
local IN_REG, IN_HOLD, IN_REGS = seam.MB_INPUT_REG_FIRST, seam.MB_INPUT_HOLDING_FIRST, seam.MB_INPUT_REGS
local IN_BIT, IN_BITS = seam.MB_INPUT_BIT_FIRST, seam.MB_INPUT_BITS
local OUT_REG, OUT_REGS, OUT_COMMANDS_REGS = seam.MB_OUTPUT_REG_FIRST, seam.MB_OUTPUT_REGS, seam.MB_OUTPUT_COMMANDS_REGS
local OUT_COIL = seam.MB_OUTPUT_COIL_FIRST
local REGIONS = {
    input_registers = { { "input", IN_REG, IN_REG + IN_REGS - 1 } },
    holding_registers = { { "output", OUT_REG, OUT_REG + OUT_REGS - 1 }, { "input", IN_HOLD, IN_HOLD + IN_REGS - 1 } },
    discrete_inputs = { { "input", IN_BIT, IN_BIT + IN_BITS - 1 } },
    coils = { { "output", OUT_COIL, OUT_COIL + OUT_REGS * 16 - 1 } },
}
local TABLE_NAMES = {
    input_registers = "Input registers", holding_registers = "Holding registers",
    discrete_inputs = "Discrete inputs", coils = "Coils",
}
-- function code -> Modbus table
local FC_TABLE = {
    [1] = "coils", [2] = "discrete_inputs", [3] = "holding_registers", [4] = "input_registers",
    [5] = "coils", [6] = "holding_registers", [15] = "coils", [16] = "holding_registers",
    [23] = "holding_registers",
}
local IS_BITS = { coils = true, discrete_inputs = true }

------------------------------------------------------------------------
-- Preferences
------------------------------------------------------------------------
local DETECT_HEURISTIC, DETECT_ALWAYS, DETECT_OFF = 0, 1, 2
-- ADUs of a connection the heuristic looks at before it gives up (the C front
-- end's bound, which counts frames: equal with one ADU a frame)
local CANDIDATE_TRIES = seam.MB_CANDIDATE_TRIES
proto.prefs.port = Pref.range("Modbus/TCP ports", "502", "TCP ports of BUs' Modbus/TCP servers, a list or "
    .. "ranges (502,5020); the port of Wireshark's Modbus/TCP dissector (mbtcp.tcp.port) is decoded too: "
    .. "a port added here or there never takes another away", 65535)
proto.prefs.detection = Pref.enum("Detection", DETECT_HEURISTIC,
    "heuristic: decode a connection once its traffic shows a BU (input images whose PCI moves every 125 ms, "
    .. "or an input image and a written output image); always: every connection on the port; off: leave "
    .. "Modbus alone (but for the BU servers listed)",
    { { 1, "heuristic", DETECT_HEURISTIC }, { 2, "always", DETECT_ALWAYS }, { 3, "off", DETECT_OFF } }, false)
proto.prefs.servers = Pref.string("BU servers", "",
    "BU Modbus/TCP servers decoded from their first frame without evidence, comma separated: an IPv4 address "
    .. "(on the Modbus/TCP port) or address:port (on that port), e.g. 192.168.2.41, 192.168.2.42:5020. "
    .. "Invalid entries are ignored and named on stderr (and in a dialog in the GUI).")
proto.prefs.swap = Pref.bool("Swap register bytes", true,
    "A register carries image byte 2n in its low 8 bits (as the BU does); off: in its high 8 bits")
proto.prefs.pci_timeout = Pref.uint("PCI timeout (ms)", 500,
    "A controller that does not read the input image for longer than this gets a poll gap warning")
-- the EC-Link mode of the BUs (TS-0007 2.1); an entry of the servers
-- preference may name its own (vrshark/modbus_servers.luam)
local MODES = { [0] = "auto", "standard", "input_commands", "input_only" }
proto.prefs.mode = Pref.enum("EC-Link mode", 0,
    "auto: Input + Commands when the controller writes only the first 20 output bytes (holding registers 0..9), "
    .. "else Standard; a PCO stall then is a warning (a fault if the BU runs in Standard mode). standard, "
    .. "input_commands, input_only: the BU runs in that mode (PCO supervised only in standard; input_only: "
    .. "no output image supervised). A server in \"BU servers\" may name its own: 192.168.2.41:502=standard",
    { { 1, "auto", 0 }, { 2, "standard", 1 }, { 3, "input_commands", 2 }, { 4, "input_only", 3 } }, false)
proto.prefs.cai_timeout = Pref.uint("CAI timeout (ms)", 2000,
    "A command to the RU (a new CCO) that CAI does not echo within this is a warning. TS-0007 8.2 gives no "
    .. "time: the limit is this project's own, by default the 2000 ms that 8.1 gives CAO")
proto.prefs.assembled = Pref.bool("Show assembled images", false,
    "Show on every EC-Link frame the input and output images as assembled from all accesses so far")

-- (port_hint(): a port some dissector sits on)
local tcp_port_table = DissectorTable.get("tcp.port")
-- preference values read once per change, not per ADU
local opt = {}

-- the servers preference, parsed when its text changes; what is wrong with
-- it said once per text (stderr, and a dialog in the GUI)
local servers_text
local function read_servers()
    local text = proto.prefs.servers or ""
    if text == servers_text then return end
    servers_text = text
    opt.servers = servers.parse(text)
    opt.any_servers = #opt.servers.list > 0
    if #opt.servers.errors > 0 then
        local msg = "vrshark: eclink_modbus.servers: " .. table.concat(opt.servers.errors, "; ")
        io.stderr:write(msg .. "\n")
        if gui_enabled() then report_failure(msg) end
    end
end

local function read_prefs()
    opt.detection, opt.swap, opt.assembled = proto.prefs.detection, proto.prefs.swap, proto.prefs.assembled
    opt.pci_timeout = proto.prefs.pci_timeout / 1000
    opt.cai_timeout = proto.prefs.cai_timeout / 1000
    opt.mode = MODES[proto.prefs.mode] or "auto"
    read_servers()
end

-- The ports, the listed servers and the hooks of the C front end
-- (vrshark/transport.luam place()): at each file start and preference
-- change.
local function place(from_init)
    transport.place(from_init, opt.servers, opt.detection == DETECT_HEURISTIC, opt.detection == DETECT_ALWAYS)
end

local function prefs_changed()
    read_prefs()
    place(false)
end
proto.prefs_changed = prefs_changed

------------------------------------------------------------------------
-- Per-capture state
------------------------------------------------------------------------
local conns      -- connection key -> connection state
local keys_by_ports -- client port * 65536 + server port -> { { client Address, server Address, key }, ... }
local streams    -- deadline key -> a BU image's stream (stream_of())
local adus       -- ADU key -> what the first pass worked out for it (but plain records: below)
-- requests on a port no setting names (port_hint): per connection what they
-- could prove (detect.requests), per frame the setting the note named
local hint_conns, hint_of, hint_short
-- per frame, worked out on its first pass: TCP data of a decoded connection
-- that does not start an ADU (mid_adu_note()), or false
local mid_adu_of

-- seconds (a difference of pcap timestamps) to the microsecond: the times a
-- record keeps (shown to the microsecond; the flat records keep them as
-- whole microseconds: one pass and two agree)
local function to_us(secs)
    return math.floor(secs * 1e6 + 0.5) / 1e6
end

-- seconds (a difference of pcap timestamps) as an NSTime, to the microsecond
local function nstime(secs)
    local us = math.floor(secs * 1e6 + 0.5)
    return NSTime.new(math.floor(us / 1e6), (us % 1000000) * 1000)
end

-- An image: its bytes as one string (shared by reference with the per-frame
-- snapshots while it does not change), which bits of each byte have been
-- seen (mask) and how many bytes are fully known.
-- (mask: a byte not written reads 0, from the metatable: every Modbus/TCP
-- connection gets two images, most of them never written)
local ZERO_MASK = { __index = function() return 0 end }
local function new_image(len)
    return { len = len, data = string.rep("\0", len), mask = setmetatable({}, ZERO_MASK), nknown = 0 }
end

local sbyte = string.byte
local function val(img, i) return sbyte(img.data, i + 1) end

-- record of an ADU of a connection that is not decoded (nothing to show)
local NOT_DECODED = {}
-- slots of a decoded ADU's record (false: none)
local R_START, R_COUNT, R_REQUEST, R_TIME, R_RESPONSE, R_PCI_AGE, R_PCO_AGE, R_ACCEPTED = 1, 2, 3, 4, 5, 6, 7, 8
local unpack = table.unpack or unpack  -- luacheck: ignore 113 (Lua 5.1/5.2 global)
local NONE = {}

-- Plain records, kept flat: the record of the first ADU of a frame's first
-- buffer that has nothing but the 8 usual values (no findings, links, notes,
-- nothing another frame still writes into) is not kept as a table of its own
-- but in these maps by frame number (vrshark/framemap.luam says why). A
-- table per ADU (about 250 bytes with its entry in `adus`) made most of the
-- plugin's memory, and its garbage collection most of its time, on long
-- captures. The maps are packed (a few bytes a frame in a string once the
-- capture has moved past a chunk of frames): values that repeat from frame
-- to frame as numbers of 3 bytes, times in whole microseconds.
--   at_key   ((rl * 4 + age kind) * 2 + has range) * 2^32 + start * 65536 + count:
--            rl the reported length of the buffer the values belong to
--            (< 2^18), age kind 0 none, 1 PCI age, 2 PCO age (a record with
--            both stays a table), has range: start and count known
--   at_age   that age (R_PCI_AGE or R_PCO_AGE)
--   at_la    accepted * LINK_SPAN + link: accepted 0 none, else the frame
--            it was accepted in (R_ACCEPTED); link 0 none, else how far the
--            linked frame lies (a request: its response's, after it; a
--            response: its request's, before it), LINK_FAR: in far_links[n]
--   at_time  a response: time since its request
local at_key, at_age, at_la, at_time, far_links
-- true in a one-pass tshark run (vrshark/passes.luam): no frame is shown
-- again, so no record is kept
local once = false
local TWO32 = 4294967296
local LINK_SPAN = 2097152
local LINK_FAR = LINK_SPAN - 1

-- the link part of at_la for frame n linked to frame `to` (nil: none)
local function link_code(n, to, is_request)
    if not to then return 0 end
    local d = is_request and to - n or n - to
    if d > 0 and d < LINK_FAR then return d end
    far_links[n] = to
    return LINK_FAR
end

-- access_list()'s lists by kind of access
local access_memo, access_memo_n

-- tshark -2 -R (vrshark/passes.luam): first-pass frame numbers repeat. No
-- record goes flat (a request's flat record takes its response's link by
-- number); the keys in `adus` of the highest number so far are listed, and
-- a frame whose number an earlier frame had forgets them first.
local renumbers = passes.renumbers()
passes.track()
local top_n, top_keys = 0, {}

local function init_state()
    read_prefs()
    once = passes.once()
    top_n, top_keys = 0, {}
    conns, keys_by_ports = {}, {}
    streams = {}
    -- (every decoder resets the shared clock at a file start; all run before the first frame)
    deadlines.reset()
    adus = {}
    hint_conns, hint_of, hint_short = {}, {}, {}
    mid_adu_of = {}
    at_key, at_age, at_la, at_time, far_links = framemap.packed_refs(), framemap.packed_us(), framemap.packed_refs(),
        framemap.packed_us(), {}
    access_memo, access_memo_n = {}, 0
end

-- The record tables the dissector is done with (kept flat, or rebuilt
-- from the flat maps for one call), used again: most frames make none.
local spare_rec = false
local function take_rec()
    local rec = spare_rec
    if not rec then return { false, false, false, false, false, false, false, false } end
    spare_rec = false
    -- (one instruction each: a loop takes three a slot)
    rec[1] = false; rec[2] = false; rec[3] = false; rec[4] = false
    rec[5] = false; rec[6] = false; rec[7] = false; rec[8] = false
    return rec
end

-- The pending request first_pass() made last (its record may go flat).
local last_request = false

-- A record with nothing beyond its array slots (next() past slot 8 finds no
-- key) goes flat: true, and its table is free once the frame is shown. A
-- request's pending entry then names its frame (flat), so that the
-- response that answers it writes its link into the maps (first_pass).
local function store_rec(key, n, rl, off, rec, is_request)
    local plain = rec ~= NOT_DECODED and #rec == 8 and next(rec, 8) == nil
    local r = last_request
    if once then
        -- a one-pass tshark run reads no record again: none is kept, and a
        -- plain one is used again by the next frame
        if plain and is_request and r and r.rec == rec then r.rec = false end
        return plain
    end
    if renumbers then
        if n ~= top_n then top_n, top_keys = n, {} end
        top_keys[#top_keys + 1] = key
        adus[key] = rec
        return false
    end
    local acc = rec[R_ACCEPTED]
    if not plain or off ~= 0 or fget(at_key, n) ~= nil or rl >= 262144 or (rec[R_PCI_AGE] and rec[R_PCO_AGE]) then
        adus[key] = rec
        return false
    end
    local kind, age = 0, false
    if rec[R_PCI_AGE] then
        kind, age = 1, rec[R_PCI_AGE]
    elseif rec[R_PCO_AGE] then
        kind, age = 2, rec[R_PCO_AGE]
    end
    if rec[R_START] then
        fset(at_key, n, ((rl * 4 + kind) * 2 + 1) * TWO32 + rec[R_START] * 65536 + rec[R_COUNT])
    else
        fset(at_key, n, (rl * 4 + kind) * 2 * TWO32)
    end
    fset(at_age, n, age)
    local la = acc and acc * LINK_SPAN or 0
    if is_request then
        fset(at_la, n, la + link_code(n, rec[R_RESPONSE] or nil, true))
    else
        fset(at_la, n, la + link_code(n, rec[R_REQUEST] or nil, false))
        fset(at_time, n, rec[R_TIME])
    end
    if is_request and r and r.rec == rec then r.rec, r.flat = false, n end
    return true
end

-- The record of an ADU (a table; a flat one rebuilt: true second), or nil:
-- not seen.
local function load_rec(key, n, rl, off, is_request)
    if once then return nil, false end
    local v = off == 0 and fget(at_key, n)
    if v then
        local hi = math.floor(v / TWO32)
        if math.floor(hi / 8) == rl then
            local la = fget(at_la, n)
            local acc, lc = math.floor(la / LINK_SPAN), la % LINK_SPAN
            local rec = take_rec()
            rec[R_ACCEPTED] = acc > 0 and acc
            if hi % 2 == 1 then
                local sc = v % TWO32
                rec[R_START], rec[R_COUNT] = math.floor(sc / 65536), sc % 65536
            end
            local kind = math.floor(hi / 2) % 4
            if kind == 1 then rec[R_PCI_AGE] = fget(at_age, n)
            elseif kind == 2 then rec[R_PCO_AGE] = fget(at_age, n) end
            local link = (lc == LINK_FAR) and far_links[n] or (lc > 0 and (is_request and n + lc or n - lc)) or nil
            if is_request then
                rec[R_RESPONSE] = link or false
            elseif link then
                rec[R_REQUEST], rec[R_TIME] = link, fget(at_time, n)
            end
            return rec, true
        end
    end
    return adus[key], false
end
-- (the port is taken at each file start, and at each change of the
-- preferences after load)
proto.init = function()
    init_state()
    health.reset()
    place(true)
end
init_state()

-- "client:port>server:port". The text is made once per connection: the
-- connections of a port pair are told apart by comparing addresses (no
-- string made per frame).
local function conn_key(pinfo, is_request, src_port, dst_port)
    local src, dst = p_src(pinfo), p_dst(pinfo)
    local ca, cp, sa, sp
    if is_request then
        ca, cp, sa, sp = src, src_port, dst, dst_port
    else
        ca, cp, sa, sp = dst, dst_port, src, src_port
    end
    local pk = cp * 65536 + sp
    local list = keys_by_ports[pk]
    if list then
        for i = 1, #list do
            local e = list[i]
            if e[1] == ca and e[2] == sa then return e[3] end
        end
    else
        list = {}
        keys_by_ports[pk] = list
    end
    local key = tostring(ca) .. ":" .. cp .. ">" .. tostring(sa) .. ":" .. sp
    list[#list + 1] = { ca, sa, key }
    return key
end

local function get_conn(key)
    local c = conns[key]
    if not c then
        c = {
            pending = {},
            input = new_image(64),
            output = new_image(224),
            accepted = nil,
            det = detect.new(),
            tries = 0,
            watch = {},        -- accepted: the run of invalid input images
            pre = {},          -- records analysed before acceptance (shown once accepted)
            periodic = nil,
            hs = handshake.new(opt.cai_timeout),
        }
        conns[key] = c
    end
    return c
end

------------------------------------------------------------------------
-- Mapping Modbus accesses to image bytes
------------------------------------------------------------------------
-- Image bytes of one access: list of pieces { kind, first, length, data =
-- the image bytes as a string, tvb_off = tvb offset of the first data byte,
-- bitmask = {[bytepos] = {mask, value}} (bits) }. A register piece gets
-- only its place here (rel: its offset from the access's data); mapped()
-- puts in its bytes.
local function map_access(tname, start, count, tvb, data_off, coil_value)
    local pieces = {}
    local swap = opt.swap
    for _, r in ipairs(REGIONS[tname]) do
        local kind, lo_a, hi_a = r[1], r[2], r[3]
        local lo = math.max(start, lo_a)
        local hi = math.min(start + count - 1, hi_a)
        if lo <= hi then
            local p = { kind = kind, addr_lo = lo, addr_hi = hi, base = lo_a }
            if not IS_BITS[tname] then
                p.first = 2 * (lo - lo_a)
                p.length = 2 * (hi - lo + 1)
                p.rel = 2 * (lo - start)
                p.swap = swap
            else
                -- bits lo..hi (addresses) = image bits (lo - lo_a) .. (hi - lo_a)
                local b0, b1 = lo - lo_a, hi - lo_a
                p.bitmask = {}
                for b = b0, b1 do
                    local v
                    if coil_value ~= nil then
                        v = coil_value
                    else
                        local k = b + lo_a - start
                        local byte = tvb(data_off + math.floor(k / 8), 1):uint()
                        v = bit.band(bit.rshift(byte, k % 8), 1)
                    end
                    local pos = math.floor(b / 8)
                    local e = p.bitmask[pos] or { 0, 0 }
                    e[1] = bit.bor(e[1], bit.lshift(1, b % 8))
                    e[2] = bit.bor(e[2], bit.lshift(v, b % 8))
                    p.bitmask[pos] = e
                end
                local fb = math.ceil(b0 / 8)
                local lb = math.floor((b1 + 1) / 8) - 1
                p.first = fb
                p.length = math.max(0, lb - fb + 1)
                local t = {}
                for pos = fb, lb do t[#t + 1] = string.char(p.bitmask[pos][2]) end
                p.data = table.concat(t)
                if p.length > 0 and (fb * 8 + lo_a - start) % 8 == 0 then
                    p.tvb_off = data_off + (fb * 8 + lo_a - start) / 8
                end
                p.swap = false
            end
            pieces[#pieces + 1] = p
        end
    end
    return pieces
end

-- map_access() of an access of the ADU at `off`, worked out once per
-- dissector call: the first pass (heuristic, watch, image store) and the
-- view of the same call use the same pieces (each worked them out again,
-- swapping the register bytes anew). Kept for the call's tvb only, compared
-- with rawequal: a Tvb of an earlier call has expired, and its __eq says
-- so; the reference kept here stops its address being taken by another.
-- One entry (an ADU has one image access; a buffer of several ADUs works
-- each out again): upvalues, no table a call.
local memo_tvb, memo_at, memo_a, memo_pieces = false, false, false, false
local function mapped(a, tvb, off)
    local at = off + a.data
    -- (the access lists are shared, access_list(): the same access is the same table)
    if rawequal(memo_tvb, tvb) and memo_at == at and rawequal(memo_a, a) then return memo_pieces end
    local pieces
    if IS_BITS[a.tname] then
        pieces = map_access(a.tname, a.start, a.count, tvb, at, a.coil)
    else
        -- registers: where the pieces lie is worked out once per access and
        -- kept on it; their bytes are put in anew on each call
        pieces = a.pieces
        if not pieces or a.pieces_swap ~= opt.swap then
            pieces = map_access(a.tname, a.start, a.count, tvb, at, a.coil)
            a.pieces, a.pieces_swap = pieces, opt.swap
        end
        for i = 1, #pieces do
            local p = pieces[i]
            p.tvb_off = at + p.rel
            local d = tvb_raw(tvb, p.tvb_off, p.length)
            if p.swap then d = image.swap_pairs(d) end
            p.data = d
        end
    end
    memo_tvb, memo_at, memo_a, memo_pieces = tvb, at, a, pieces
    return pieces
end

-- Does an access cover a whole input image (the heuristic looks at those;
-- the C front end's mb_evidence_request() asks the same)?
local function full_input(tname, start, count)
    local regions = REGIONS[tname]
    for i = 1, #regions do
        local r = regions[i]
        if r[1] == "input" and start <= r[2] and start + count - 1 >= r[3] then return true end
    end
    return false
end

-- Is a write the whole output image (OUT_COMMANDS_REGS or OUT_REGS holding
-- registers from OUT_REG)?
local function full_output_write(a)
    return a.write and a.tname == "holding_registers" and a.start == OUT_REG
        and (a.count == OUT_COMMANDS_REGS or a.count == OUT_REGS)
end

-- Does a read request (function 2, 3, 4 or 23) cover PCI, input image byte 0?
local READS = { [2] = true, [3] = true, [4] = true, [23] = true }
local function reads_pci(fc, r)
    if not (READS[fc] and r.count) then return false end
    local bits = IS_BITS[FC_TABLE[fc]] and 7 or 0
    for _, reg in ipairs(REGIONS[FC_TABLE[fc]]) do
        if reg[1] == "input" and r.start <= reg[2] and r.start + r.count - 1 >= reg[2] + bits then return true end
    end
    return false
end

-- The heuristic's look at an ADU of a connection not accepted yet.
local function look(c, accesses, tvb, off, t)
    local yes = false
    for i = 1, #accesses do
        local a = accesses[i]
        local inp, outp = full_input(a.tname, a.start, a.count), full_output_write(a)
        if inp or outp then
            local pieces = mapped(a, tvb, off)
            for j = 1, #pieces do
                local p = pieces[j]
                if inp and p.kind == "input" and p.length == 64 then
                    yes = detect.input(c.det, p.data, t) or yes
                elseif outp and p.kind == "output" then
                    yes = detect.output(c.det, p.data) or yes
                end
            end
        end
    end
    return yes
end

-- An accepted connection's full input images, watched: false once
-- detect.DROP_IMAGES of them in a row were invalid.
local function still_valid(c, accesses, tvb, off)
    for i = 1, #accesses do
        local a = accesses[i]
        if full_input(a.tname, a.start, a.count) then
            local pieces = mapped(a, tvb, off)
            for j = 1, #pieces do
                local p = pieces[j]
                if p.kind == "input" and p.length == 64 and not detect.still_valid(c.watch, p.data) then
                    return false
                end
            end
        end
    end
    return true
end

-- Apply a piece to the connection's stored image.
local function store_piece(c, p)
    local img = c[p.kind]
    local mask = img.mask
    if p.bitmask then
        local t = { img.data:byte(1, -1) }
        for pos, e in pairs(p.bitmask) do
            t[pos + 1] = bit.bor(bit.band(t[pos + 1], bit.bnot(e[1]) % 256), e[2])
            if mask[pos] ~= 255 then
                mask[pos] = bit.bor(mask[pos], e[1])
                if mask[pos] == 255 then img.nknown = img.nknown + 1 end
            end
        end
        img.data = string.char(unpack(t))
    elseif p.length > 0 then
        if p.length == img.len then
            img.data = p.data  -- the whole image (the usual poll): no pieces cut and joined
        else
            local d = img.data
            img.data = d:sub(1, p.first) .. p.data .. d:sub(p.first + p.length + 1)
        end
        if img.nknown < img.len then
            for i = p.first, p.first + p.length - 1 do
                if mask[i] ~= 255 then
                    mask[i] = 255
                    img.nknown = img.nknown + 1
                end
            end
        end
    end
end

-- the assembled image as of now: one snapshot object per image content,
-- shared by every frame until the image changes
local function snapshot(c, kind)
    local img = c[kind]
    local s = c["snap_" .. kind]
    if not s or s.data ~= img.data or s.known ~= img.nknown then
        s = { data = img.data, known = img.nknown }
        c["snap_" .. kind] = s
    end
    return s
end

local function known(img, off, len)
    if img.nknown == img.len then return true end
    for i = off, off + len - 1 do
        if img.mask[i] ~= 255 then return false end
    end
    return true
end

------------------------------------------------------------------------
-- Handshake analysis and periodic reassembly (first pass only)
------------------------------------------------------------------------
-- per-frame findings and links: tables made when the first one is added
local function add_finding(rec, fd)
    if not rec.findings then rec.findings = {} end
    rec.findings[#rec.findings + 1] = fd
end

local function set_link(rec, name, v)
    if not rec.links then rec.links = {} end
    rec.links[name] = v
end

-- the image values handshake.update() reads (it keeps none of the tables)
local in_values, out_values = { pci = false, cci = false, cai = false, bu = false }, { pco = 0, cco = 0, cao = 0 }

local function analyse(c, rec, t, frame, touched_in, touched_out)
    local inp, out = c.input, c.output
    local iv, ov
    if touched_in then
        iv = in_values
        if known(inp, 0, 4) then
            local pci, cci, _, cai = sbyte(inp.data, 1, 4)
            iv.pci, iv.cci, iv.cai = pci, cci, cai
        else
            iv.pci, iv.cci, iv.cai = nil, nil, nil
        end
        iv.bu = known(inp, 20, 1) and val(inp, 20) or nil
    end
    -- (Input Only mode: no output image to supervise)
    if touched_out and known(out, 0, 4) and c.mode ~= "input_only" then
        ov = out_values
        local pco, cco, _, cao = sbyte(out.data, 1, 4)
        ov.pco, ov.cco, ov.cao = pco, cco, cao
        if c.mode == "auto" then
            -- a controller that has written only the first 20 bytes (10 holding
            -- registers) is taken for Input + Commands mode (TS-0007 2.1, 5.2):
            -- a guess, which the PCO stall's warning then names
            ov.len = known(out, 20, 2) and 224 or handshake.COMMANDS_LEN
            ov.guessed = ov.len == handshake.COMMANDS_LEN
        else
            ov.len = c.mode == "standard" and 224 or handshake.COMMANDS_LEN
            ov.guessed = false
        end
        -- the mode's note waits for a frame of the recognised connection
        -- (one pass shows none before it)
        ov.pending = rec.pending
    end
    local r = handshake.update(c.hs, iv, ov, t, frame, rec)
    -- (numeric loops: the lists are empty on most frames)
    local fds, back = r.findings, r.back
    for i = 1, #fds do
        local fd = fds[i]
        add_finding(rec, { ef[fd[1]] or false, fd[2], once = fd.once and { ef[fd.once[1]], fd.once[2] } })
        if fd[3] then set_link(rec, fd[3], fd[4]) end
    end
    if next(r.links) then
        for k, v in pairs(r.links) do set_link(rec, k, v) end
    end
    for i = 1, #back do
        local b = back[i]
        set_link(b[1], b[2], b[3])
        if b[4] then add_finding(b[1], { ef[b[4][1]], b[4][2] }) end
        if b[4] then health.modbus_later(ef[b[4][1]]) end
    end
    rec[R_PCI_AGE], rec[R_PCO_AGE] = r.pci_age and to_us(r.pci_age) or false, r.pco_age and to_us(r.pco_age) or false
    -- (a nil stored under a new key would make the record a hash part)
    if r.bu_state_prev ~= nil then rec.bu_state_prev = r.bu_state_prev end
    -- periodic output multiplexing (vrshark/eclink_periodic.luam)
    if touched_out and known(out, 0, 1) and known(out, 20, 3) then
        local s1, s2, block = sbyte(out.data, 21, 23)
        local size = s1 * 256 + s2
        local blen = periodic.block_len(size, block)
        local data = blen and known(out, 24, blen) and out.data:sub(25, 24 + blen) or nil
        c.periodic = c.periodic or {}
        local got = periodic.add(c.periodic, size, block, sbyte(out.data, 1), data, frame, rec)
        if got then rec.held = true end  -- gets a link later: kept as a table
        if type(got) == "table" then
            for i, brec in ipairs(got.recs) do
                if got.frames[i] ~= frame then set_link(brec, "periodic_reassembled_in", frame) end
            end
            rec.periodic = { data = got.data, frames = got.frames }
            add_finding(rec, { ef.periodic_reassembled, string.format(
                "Periodic data reassembled: %d bytes from %d blocks", got.size, got.n) })
        end
    end
end

------------------------------------------------------------------------
-- Streams that stop (first pass only)
------------------------------------------------------------------------
-- TS-0007 8.3 and 8.4 are rules on the images, not on the TCP connection:
-- a stream is a BU's (server address:port, unit) input image read, or its
-- output image written, over any of the PLC's connections to it. Every
-- read or write arms its deadline on the shared clock (vrshark/deadlines);
-- the first frame any plugin dissects after it carries the finding.
-- (in a block: the main chunk is near Lua's limit of 200 locals)
local stream_frame, streams_dropped, tap_tcp
do
    local STREAM = {
        input = { expert = "input_missing", what = "input image not read", last = "read", tag = "no input",
                  rule = "PCI timeout", spec = "TS-0007 8.3" },
        output = { expert = "output_missing", what = "output image not written", last = "written",
                   tag = "no output", rule = "PCO timeout", spec = "TS-0007 8.4" },
    }

    -- what a finding of the clock adds to the frame that carries it: a
    -- generated item of this protocol with the links and the expert, the tag in
    -- Info (pinfo.cols: the frame may be any plugin's, and this is rare)
    local function clock_show(expert_field, text, tag, links)
        return function(tvb, pinfo, tree)
            local item = add(tree, proto, tvb:range(0, 0))
            set_generated(item)
            append_text(item, ": " .. text)
            for i = 1, #links, 2 do set_generated(add(item, links[i], links[i + 1])) end
            item:add_proto_expert_info(expert_field, text)
            pinfo.cols.info:append(tag)
        end
    end

    local function stream_of(kind, bu, unit)
        local key = "eclink_modbus " .. kind .. " " .. bu .. " unit " .. unit
        local s = streams[key]
        if s then return s end
        local k = STREAM[kind]
        s = { key = key, kind = kind, bu = bu, unit = unit, frame = false, t = false, limit = false }
        s.fire = function(_, now)
            local gap = now - s.t
            local text = string.format("BU %s unit %d: %s for %.3f s (%s %.3f s, %s): last %s in frame %d",
                bu, unit, k.what, gap, k.rule, s.limit, k.spec, k.last, s.frame)
            health.modbus_finding(s.c, unit, ef[k.expert])  -- a stall of the stream's row
            return clock_show(ef[k.expert], text, string.format(" [%s %.3f s]", k.tag, gap),
                { pf.missing_since, s.frame, pf.missing_time, nstime(gap) })
        end
        streams[key] = s
        return s
    end

    -- a frame of the stream (a request to the BU): its deadline moves on. The
    -- connection keeps its own last frame of each image (c.f_in, c.f_out, by
    -- unit): what its close names, also when the close is worked out on a
    -- later pass and the stream went on over another connection.
    function stream_frame(c, kind, unit, number, abs, limit, pinfo)
        local input = kind == "input"
        local by_unit = c[input and "s_in" or "s_out"]
        if not by_unit then
            by_unit = {}
            c[input and "s_in" or "s_out"], c[input and "f_in" or "f_out"] = by_unit, {}
        end
        local s = by_unit[unit]
        if not s then
            s = stream_of(kind, tostring(pinfo.dst) .. ":" .. pinfo.dst_port, unit)
            by_unit[unit] = s
        end
        c[input and "f_in" or "f_out"][unit] = number
        s.frame, s.t, s.limit, s.c = number, abs, limit, c
        deadlines.arm(s.key, abs + limit, s.fire)
    end

    -- a connection no longer taken for a BU's: its streams are none
    function streams_dropped(c)
        for _, list in ipairs({ c.s_in or NONE, c.s_out or NONE }) do
            for _, s in pairs(list) do deadlines.disarm(s.key) end
        end
    end

    -- the last frames of a connection's image streams, for the close finding
    local function last_frames(c)
        local parts = {}
        for _, kind in ipairs({ "input", "output" }) do
            local list = c[kind == "input" and "f_in" or "f_out"]
            local any = false
            for unit, frame in pairs(list or NONE) do
                any = true
                parts[#parts + 1] = string.format("%s image (unit %d) last %s in frame %d", kind, unit,
                    STREAM[kind].last, frame)
            end
            if not any then parts[#parts + 1] = string.format("%s image not %s on it", kind, STREAM[kind].last) end
        end
        return table.concat(parts, ", ")
    end

    -- The TCP segments that end a connection carry no payload, and TCP hands
    -- none of those to a subdissector: a listener of the tcp tap sees them.
    -- With the C plugin its listener (plugins/vrshark/vrshark-tcpends.c)
    -- keeps those of the connections named to it, and the front ends hand
    -- them over (transport.tcp_ends()) before their own work on the next
    -- frame they see. Without it a Lua listener (no filter: no tree forced)
    -- costs a Lua call and a table of the TCP header on every TCP frame (a
    -- sixth of a BU's Modbus/TCP with -Y, docs/quality.md), so it is made
    -- when the first connection is taken for a BU's, and stays for the
    -- process. A FIN or RST on a BU's connection is said on the next frame a
    -- plugin dissects (the tap runs after the frame's own dissection),
    -- naming the frame that ended it.
    local FIN, RST = 1, 4
    -- tshark -2 runs the taps in its second pass only (Wireshark in the first)
    local taps_late = passes.tshark() and not passes.once()
    local function find_conn(pinfo, sport, dport)
        local src, dst = p_src(pinfo), p_dst(pinfo)
        local list = keys_by_ports[sport * 65536 + dport]
        for i = 1, list and #list or 0 do
            local e = list[i]
            if e[1] == src and e[2] == dst then return conns[e[3]], true, e[3] end
        end
        list = keys_by_ports[dport * 65536 + sport]
        for i = 1, list and #list or 0 do
            local e = list[i]
            if e[1] == dst and e[2] == src then return conns[e[3]], false, e[3] end
        end
        return nil
    end

    -- connection `key` (c) ended in frame `number` (time abs) by a segment
    -- with TCP flags `flags` from the client or the BU
    local function ended(c, key, from_client, number, flags, abs)
        -- (a tap runs on every pass: the first frame that ends the connection counts)
        if not c or c.ended or not (c.accepted or c.armed) then return end
        c.ended = number
        local reset = bit.band(flags, RST) ~= 0
        local client, bu = key:match("^(.*)>(.*)$")
        local text = string.format("TCP connection of the PLC (%s) to BU %s %s in frame %d (from the %s): %s",
            client, bu, reset and "reset by RST" or "closed by FIN", number, from_client and "PLC" or "BU",
            last_frames(c))
        -- (counted in the health rows once a frame carries it)
        local function counted()
            for unit in pairs(c.health or NONE) do
                health.modbus_finding(c, unit, reset and ef.connection_reset or ef.connection_closed)
            end
        end
        local show = clock_show(reset and ef.connection_reset or ef.connection_closed, text,
            reset and " [connection to BU reset]" or " [connection to BU closed]", { pf.closed_in, number })
        if taps_late then
            deadlines.later(number, show, counted)
        else
            -- (due just before this frame's time: the next frame dissected fires it)
            deadlines.arm("eclink_modbus end " .. key, abs - 1e-6, function()
                counted()
                return show
            end)
        end
    end

    local function tcp_tap(pinfo, _, th)
        local flags = th.th_flags
        if not flags or bit.band(flags, FIN + RST) == 0 then return end
        local c, from_client, key = find_conn(pinfo, th.th_sport, th.th_dport)
        if c then ended(c, key, from_client, p_number(pinfo), flags, p_abs_ts(pinfo)) end
    end
    -- (from the C plugin's listener: the connection by its key)
    transport.tcp_ends(function(key, from_client, number, flags, abs)
        ended(conns[key], key, from_client, number, flags, abs)
    end)
    local tapping = false
    -- connection `key` taken for a BU's on this frame (its client on
    -- client_port): named to the C plugin's listener, else the Lua one
    function tap_tcp(key, client_port)
        if tapping then return end
        if transport.tcp_end_watch(key, client_port) then return end
        tapping = true
        Listener.new("tcp", nil, false).packet = tcp_tap
    end
end

------------------------------------------------------------------------
-- One ADU
------------------------------------------------------------------------
-- into: an emptied table to fill (first_pass(): the spare one), or nil
local function parse_request_pdu(tvb, off, len, fc, into)
    -- returns start, count, data offset (writes), coil value (fc 5)
    local r = into or {}
    if len < 5 then return nil end
    -- (the fields read from one raw string: a TvbRange and a method call
    -- per field cost more than the rest of a foreign ADU's first pass)
    if fc == 1 or fc == 2 or fc == 3 or fc == 4 then
        local a1, a2, c1, c2 = sbyte(tvb_raw(tvb, off + 1, 4), 1, 4)
        r.start, r.count = a1 * 256 + a2, c1 * 256 + c2
    elseif fc == 5 or fc == 6 then
        local a1, a2, v1, v2 = sbyte(tvb_raw(tvb, off + 1, 4), 1, 4)
        r.start, r.count = a1 * 256 + a2, 1
        r.wstart, r.wcount, r.wdata = r.start, 1, off + 3
        if fc == 5 then
            local v = v1 * 256 + v2
            r.coil = (v == 0xFF00) and 1 or ((v == 0) and 0 or nil)
            if r.coil == nil then r.wstart = nil end
        end
    elseif fc == 15 or fc == 16 then
        if len < 6 then return nil end
        local a1, a2, c1, c2, bc = sbyte(tvb_raw(tvb, off + 1, 5), 1, 5)
        r.start, r.count = a1 * 256 + a2, c1 * 256 + c2
        local need = (fc == 15) and math.ceil(r.count / 8) or 2 * r.count
        if len >= 6 + need and bc >= need then
            r.wstart, r.wcount, r.wdata = r.start, r.count, off + 6
        end
    elseif fc == 23 then
        if len < 10 then return nil end
        local s1, s2, c1, c2, w1, w2, x1, x2 = sbyte(tvb_raw(tvb, off + 1, 8), 1, 8)
        r.start, r.count = s1 * 256 + s2, c1 * 256 + c2
        local ws, wc = w1 * 256 + w2, x1 * 256 + x2
        if len >= 10 + 2 * wc then
            r.wstart, r.wcount, r.wdata = ws, wc, off + 10
        end
    else
        return nil
    end
    return r
end

-- The image accesses of an ADU: r is its parsed request PDU (a request) or
-- { start =, count = } of its request (a response), nil when unknown.
-- Worked out again for the tree rather than stored per frame.
-- The lists are made once per kind of access (a controller polls the same
-- ranges again and again) and shared: nobody changes them but mapped(),
-- which keeps the places of their pieces on them (access_memo: init_state).
local function access_list(fc, start, count, data, coil, write)
    local k = ((((fc * 64 + data) * 4 + (coil or 2)) * 2 + (write and 1 or 0)) * 65536 + start) * 65536 + count
    local l = access_memo[k]
    if not l then
        l = { { tname = FC_TABLE[fc], start = start, count = count, data = data, coil = coil, write = write } }
        if data < 64 then
            if access_memo_n >= 4096 then access_memo, access_memo_n = {}, 0 end
            access_memo[k], access_memo_n = l, access_memo_n + 1
        end
    end
    return l
end

local function adu_accesses(tvb, off, adu_len, fcb, is_request, r)
    if not r then return NONE end
    local fc = fcb % 128  -- (the function code byte without its exception bit)
    if is_request then
        if r.wstart then
            return access_list(fc, r.wstart, r.wcount, r.wdata - off, r.coil, true)
        end
    elseif fcb < 128 and (fc <= 4 or fc == 23) and adu_len >= 9 then
        local bc = tvb_raw(tvb, off + 8, 1):byte()
        local need = (fc <= 2) and math.ceil(r.count / 8) or 2 * r.count
        if bc >= need and adu_len - 7 >= 2 + need then
            return access_list(fc, r.start, r.count, 9, nil, nil)
        end
    end
    return NONE
end

-- The accesses of the ADU the first pass worked out last: the view of the
-- same dissector call takes them (rawequal: see mapped()).
local fp_tvb, fp_off, fp_accesses = false, false, NONE

-- A pending request's table, used again once its response is worked out
-- (emptied: parse_request_pdu() and first_pass() set its keys again).
local spare_req = false
local function take_req()
    local r = spare_req
    if r then
        spare_req = false
        r.start, r.count, r.wstart, r.wcount, r.wdata, r.coil = nil, nil, nil, nil, nil, nil
        r.frame, r.t, r.rec, r.flat = nil, nil, nil, nil
    end
    return r
end

-- A connection's server, the first time: named in eclink_modbus.servers
-- (pinned: decoded from the first frame), its EC-Link mode, and the setting
-- that would name it.
local function pin(c, pinfo, is_request)
    local addr = tostring(is_request and pinfo.dst or pinfo.src)
    local port = is_request and pinfo.dst_port or pinfo.src_port
    c.pinned = opt.any_servers and servers.listed(opt.servers, addr, port, pinfo.match_uint) or false
    c.mode = c.pinned and servers.mode(opt.servers, addr, port, pinfo.match_uint) or opt.mode
    c.setting = servers.setting(addr, port, proto.prefs.servers)
end

-- A request kept pending for its response, or a response paired with its
-- request (connection + transaction + unit + function code): the record's
-- range and links. Returns the request (parsed, or the pending one), nil
-- when unknown.
local function pair(c, rec, tvb, pdu, plen, fc, tkey, is_request, number, t)
    local r
    if is_request then
        r = parse_request_pdu(tvb, pdu, plen, fc, take_req())
        if r then
            r.frame, r.t, r.rec = number, t, rec
            c.pending[tkey] = r
            last_request = r
            rec[R_START], rec[R_COUNT] = r.start, r.count
        end
        return r
    end
    r = c.pending[tkey]
    if r then
        c.pending[tkey] = nil
        rec[R_REQUEST] = r.frame
        rec[R_TIME] = to_us(t - r.t)
        local flat = r.flat
        if flat then
            -- (a flat request: its response's frame goes into at_la)
            local la = fget(at_la, flat)
            fset(at_la, flat, la - la % LINK_SPAN + link_code(flat, number, true))
        elseif r.rec then
            r.rec[R_RESPONSE] = number
        end
        rec[R_START], rec[R_COUNT] = r.start, r.count
    else
        rec.no_request = true
    end
    return r
end

-- The heuristic's turn on a connection not accepted yet: from the first
-- evidence on, a candidate's ADUs are analysed like an accepted
-- connection's, and shown once it is accepted. False: the ADU stays
-- Modbus's.
local function judge(c, rec, accesses, tvb, off, t, number)
    if c.tries >= CANDIDATE_TRIES then return false end
    c.tries = c.tries + 1
    c.det.shaped = nil
    if look(c, accesses, tvb, off, t) then
        c.accepted = number
        for _, pr in ipairs(c.pre) do pr[R_ACCEPTED] = number end
        c.pre = nil
    elseif detect.candidate(c.det) then
        rec.pending = true
        c.pre[#c.pre + 1] = rec
        if c.det.shaped then
            -- never silent: what is missing, and the setting that decodes it now
            local missing = detect.missing(c.det)
            rec.hint = string.format("Looks like a BU (%s), not recognised: needs %s; to decode it now: %s",
                c.det.shaped,
                missing ~= "" and missing or "more of its traffic", c.setting)
            rec.hint_setting = c.setting
        end
    else
        return false
    end
    return true
end

-- An accepted connection whose input images stopped being valid: judged
-- afresh from the next ADU on; this one says so (a note, instead of alarms
-- on every frame of a device that is not, or no longer, a BU).
local function drop(c, rec, pinfo, is_request, src_port, dst_port)
    add_finding(rec, { ef.dropped, string.format(
        "%d input images in a row not valid: connection (recognized in frame %d) no longer taken for a BU's; "
        .. "left to Modbus/TCP until it is recognized again", detect.DROP_IMAGES, c.accepted) })
    rec[R_ACCEPTED] = c.accepted
    streams_dropped(c)
    conns[conn_key(pinfo, is_request, src_port, dst_port)] = nil
    return rec
end

-- poll gap: the first read of the input image after more than the PCI timeout
local function poll(c, rec, t, number)
    if c.last_read and t - c.last_read > opt.pci_timeout then
        local gap = t - c.last_read
        rec.poll_gap, rec.poll_gap_from = gap, c.last_read_frame
        add_finding(rec, { ef.poll_gap, string.format("Input image not read for %.3f s (PCI timeout %.3f s)",
            gap, opt.pci_timeout) })
    end
    c.last_read, c.last_read_frame = t, number
end

-- The ADU's image bytes into the connection's images: which image it
-- touched, and whether a request wrote PCO (output byte 0).
local function store_accesses(c, accesses, tvb, off, is_request)
    local touched_in, touched_out, wrote_pco = false, false, false
    for i = 1, #accesses do
        local pieces = mapped(accesses[i], tvb, off)
        for j = 1, #pieces do
            local p = pieces[j]
            store_piece(c, p)
            if p.kind == "input" then
                touched_in = true
            else
                touched_out = true
                if is_request and p.first == 0 then wrote_pco = true end
            end
        end
    end
    return touched_in, touched_out, wrote_pco
end

-- the BU's streams (a connection taken for a BU's only): the input image
-- read (its PCI), the output image written where the mode has periodic
-- output (Standard, given or guessed from writes past the 20 bytes of
-- Input + Commands mode: TS-0007 2.1, 8.4)
local function arm_streams(c, unit, number, pinfo, reads, wrote_pco, key, client_port)
    if not c.armed then
        c.armed = true
        tap_tcp(key, client_port)
    end
    if reads then
        stream_frame(c, "input", unit, number, p_abs_ts(pinfo), opt.pci_timeout, pinfo)
    end
    if wrote_pco and (c.mode == "standard" or c.mode == "auto" and known(c.output, 20, 2)) then
        stream_frame(c, "output", unit, number, p_abs_ts(pinfo), handshake.LIMITS.pco, pinfo)
    end
end

-- First pass: work out what this ADU means and update the connection.
local function first_pass(tvb, pinfo, off, adu_len, is_request, tid, unit, fcb, number, src_port, dst_port)
    local fc = fcb % 128
    local tname = FC_TABLE[fc]
    if not tname then return NOT_DECODED end
    local key = conn_key(pinfo, is_request, src_port, dst_port)
    local c = get_conn(key)
    if c.pinned == nil then pin(c, pinfo, is_request) end
    -- a connection the heuristic gave up on stays Modbus's: nothing more to work out
    if c.tries >= CANDIDATE_TRIES and not c.accepted and not c.pinned and opt.detection == DETECT_HEURISTIC then
        last_request = false
        return NOT_DECODED
    end
    -- (every rule of the connection goes by a time that never runs
    -- backwards: a clock step is a finding, no time shown is negative)
    local t, step = handshake.clock(c.hs, p_abs_ts(pinfo), number,
        "the PCI, PCO, command deadline and poll gap rules")
    -- the usual per-frame values in the array part (8 slots, no hash part)
    local rec = take_rec()
    if step then add_finding(rec, { ef.time_backwards, step[2] }) end
    last_request = false
    local r = pair(c, rec, tvb, off + 7, adu_len - 7, fc, (tid * 256 + unit) * 256 + fc, is_request, number, t)
    local accesses = adu_accesses(tvb, off, adu_len, fcb, is_request, r)
    -- (a response's request is done with: nobody keeps it)
    if r and not is_request then spare_req = r end
    fp_tvb, fp_off, fp_accesses = tvb, off, accesses
    -- a listed server: decoded from the first frame, as with "always"
    local det = c.pinned and DETECT_ALWAYS or opt.detection
    if det == DETECT_OFF then return NOT_DECODED end
    if det == DETECT_HEURISTIC and not c.accepted and not judge(c, rec, accesses, tvb, off, t, number) then
        return NOT_DECODED
    end
    if det == DETECT_HEURISTIC and c.accepted and c.accepted ~= number
        and not still_valid(c, accesses, tvb, off) then
        return drop(c, rec, pinfo, is_request, src_port, dst_port)
    end
    rec[R_ACCEPTED] = c.accepted or false
    local reads = is_request and r and reads_pci(fc, r)
    if reads then poll(c, rec, t, number) end
    local touched_in, touched_out, wrote_pco = store_accesses(c, accesses, tvb, off, is_request)
    if c.accepted or det == DETECT_ALWAYS then
        arm_streams(c, unit, number, pinfo, reads, wrote_pco, key, is_request and src_port or dst_port)
    end
    analyse(c, rec, t, number, touched_in, touched_out)
    health.modbus(c, rec, pinfo, is_request and dst_port or src_port, unit, is_request,
        reads, is_request and touched_out, touched_in, det ~= DETECT_HEURISTIC or c.accepted, t, number)
    if opt.assembled then
        rec.snap_in = snapshot(c, "input")
        rec.snap_out = snapshot(c, "output")
    end
    return rec
end

local function bit_text(p)
    -- partial bytes touched by a bit access
    local out = {}
    local layout = image.layout[p.kind]
    for pos, e in pairs(p.bitmask) do
        if e[1] ~= 255 then
            local name = "?"
            for _, l in ipairs(layout) do
                if pos >= l.off and pos < l.off + l.len then name = l.name end
            end
            local lo, hi
            for b = 0, 7 do
                if bit.band(e[1], bit.lshift(1, b)) ~= 0 then
                    lo = lo or b
                    hi = b
                end
            end
            out[#out + 1] = { pos, string.format("%s image byte %d bits %d-%d (%s)", p.kind, pos, lo, hi, name) }
        end
    end
    table.sort(out, function(a, b) return a[1] < b[1] end)
    return out
end

local function show_assembled(tree, pinfo, snap, kind)
    if not snap then return end
    local len = (kind == "input") and 64 or 224
    if kind == "output" and snap.data:byte(21) == 0 and snap.known <= 20 then len = 20 end
    local ti = tree:add(pf.assembled, string.format("%s image as of this frame (%d of %d bytes seen)",
        kind, snap.known, len))
    ti:set_generated()
    if snap.known == 0 then return end
    local ba = ByteArray.new()
    ba:set_size(len)
    for i = 0, len - 1 do ba:set_index(i, snap.data:byte(i + 1)) end
    local tvb = ba:tvb("Assembled " .. kind .. " image")
    image.dissect(tvb, pinfo, ti, { kind = kind, image_len = len, generated = true, quiet = true })
end

-- the BU: the server, whichever way the ADU goes
local function server_text(pinfo, is_request)
    if is_request then return tostring(pinfo.dst) .. ":" .. pinfo.dst_port end
    return tostring(pinfo.src) .. ":" .. pinfo.src_port
end

------------------------------------------------------------------------
-- Sparse display: an invisible tree (the packet list, -Y, -z taps)
------------------------------------------------------------------------
-- Wireshark throws away every item of an invisible tree that nobody
-- references: show_sparse() (a sparse plan) adds only the referenced EC-Link
-- image fields (vrshark/eclink_image.luam, opts.only) and these facts of the
-- ADU, flat under the caller's tree, in the occurrences of the full tree
-- (tests/test_sparse_view.py), the expert info when it is looked at (flat,
-- in the full tree's order), and works out the Info text. Anything else
-- referenced (an expert, machine data, the protocol itself, ...) means the
-- full tree. c: { rec, tree, pinfo, is_request }
local function rec_value(field, key, as_time)
    return function(c)
        local v = c.rec[key]
        if v then c.tree:add(field, as_time and nstime(v) or v) end
    end
end

-- a time of the record in whole milliseconds (the hidden *_age_ms fields)
local function rec_ms(field, key)
    return function(c)
        local v = c.rec[key]
        if v then c.tree:add(field, record.whole_ms(v)) end
    end
end

local function link_value(field, name, as_time)
    return function(c)
        local v = (c.rec.links or NONE)[name]
        if v then c.tree:add(field, as_time and nstime(v) or v) end
    end
end

local SPARSE_ADDERS = {
    ["eclink_modbus.accepted_in"] = rec_value(pf.accepted_in, R_ACCEPTED),
    ["eclink_modbus.request_in"] = rec_value(pf.request_in, R_REQUEST),
    ["eclink_modbus.time"] = function(c)
        if c.rec[R_REQUEST] then c.tree:add(pf.time, nstime(c.rec[R_TIME])) end
    end,
    ["eclink_modbus.response_in"] = rec_value(pf.response_in, R_RESPONSE),
    ["eclink_modbus.pci_age"] = rec_value(pf.pci_age, R_PCI_AGE, true),
    ["eclink_modbus.pco_age"] = rec_value(pf.pco_age, R_PCO_AGE, true),
    ["eclink_modbus.pci_age_ms"] = rec_ms(pf.pci_age_ms, R_PCI_AGE),
    ["eclink_modbus.pco_age_ms"] = rec_ms(pf.pco_age_ms, R_PCO_AGE),
    ["eclink_modbus.poll_gap_time"] = rec_value(pf.poll_gap_time, "poll_gap", true),
    ["eclink_modbus.poll_gap_from"] = function(c)
        if c.rec.poll_gap then c.tree:add(pf.poll_gap_from, c.rec.poll_gap_from) end
    end,
    ["eclink_modbus.bu_state_prev"] = rec_value(pf.bu_state_prev, "bu_state_prev"),
    ["eclink_modbus.server"] = function(c) c.tree:add(pf.server, server_text(c.pinfo, c.is_request)) end,
}
for _, name in ipairs({ "pci_since", "pco_since", "cmd_from_ru_in", "cao_in", "cmd_to_ru_in", "cai_in",
                      "deadline_in" }) do
    SPARSE_ADDERS["eclink_modbus." .. name] = link_value(pf[name], name)
end
for _, name in ipairs({ "cmd_from_ru_latency", "cmd_to_ru_latency" }) do
    SPARSE_ADDERS["eclink_modbus." .. name] = link_value(pf[name], name, true)
end
-- the image adds its own fields (opts.only)
image.own_fields(SPARSE_ADDERS, function() end)
-- no expert names: any referenced expert means the full tree
local SPARSE = { adders = SPARSE_ADDERS, experts = {}, prefixes = { "eclink_modbus", "eclink", "vrshark_io",
                                                                   "vrshark.io" } }

-- The sparse plan for this view, or nil: the full tree.
local function sparse_plan(view)
    if not view or view.quiet or opt.assembled then return nil end
    local p = fe.plan(view, SPARSE)
    -- machine data can add findings and Info tags of its own
    if not p or ((p.cols or p.experts) and next(iodata.areas)) then return nil end
    p.only = view.fields
    return p
end

-- Where the image bytes of a piece (map_access()) are: the frame, or the
-- bytes of a bit access as a data source of their own.
local function piece_source(tvb, p)
    if p.tvb_off then return tvb, p.tvb_off end
    return ByteArray.new(p.data, true):tvb("EC-Link image bytes from bits"), 0
end

-- The Info tags of an ADU after those of its images: every frame past a
-- counter's limit says so, not only the one with the finding; [unacked] (a
-- command whose deadline passed, on the command's frame on a second pass,
-- and on every pass on the frame that saw the deadline pass: a live packet
-- list draws a row once, before a later frame can mark its command), [late
-- ack] (an echo after it).
local function adu_tags(rec, pinfo)
    local tags = handshake.tags(rec[R_PCI_AGE], rec[R_PCO_AGE])
    local fds = rec.findings
    if not fds then return tags end  -- (the usual ADU)
    local unacked, late_ack
    local visited = p_visited(pinfo)
    for i = 1, #fds do
        local ex = handshake.shown(fds[i], visited)
        if ex == ef.cmd_from_ru_late or ex == ef.cmd_to_ru_late or ex == ef.cmd_from_ru_deadline
                or ex == ef.cmd_to_ru_deadline then unacked = true end
        if ex == ef.cmd_from_ru_late_ack or ex == ef.cmd_to_ru_late_ack then late_ack = true end
    end
    if unacked then tags = tags .. " [unacked]" end
    if late_ack then tags = tags .. " [late ack]" end
    return tags
end

-- The handshake links and latencies of an ADU (rec.links), in display order.
local LINK_NAMES = { "pci_since", "pco_since", "cmd_from_ru_in", "cao_in", "cmd_to_ru_in", "cai_in", "deadline_in",
                     "periodic_reassembled_in" }
local LATENCY_NAMES = { "cmd_from_ru_latency", "cmd_to_ru_latency" }

-- The request's start and count as parse_request_pdu() gives them (a
-- response's accesses need no more).
local function request_of(rec)
    return { start = rec[R_START], count = rec[R_COUNT] }
end

-- The sparse view's context for its adders, and the options of its images:
-- one table each, filled anew for every ADU (nobody keeps them).
local sparse_ctx = {}
local sparse_opts = {}
-- The Info text of this call's images as parts (strings made once), for the
-- C plugin's append_info(): info_np of them in info_parts (set to 0 by each
-- call of the dissector).
local info_parts, info_np = {}, 0

-- The sparse view's images: only the referenced image fields (opts.only)
-- and, with the columns, their Info text (as parts for the C plugin's
-- append_info(), else in `infos`). Returns infos (NONE: nothing went in).
local function sparse_images(tvb, pinfo, tree, off, adu_len, rec, is_request, fcb, sp, root)
    local cols, experts = sp.cols, sp.experts
    -- (no columns: no Info text, no image summaries; infos: made when
    -- something goes in, which through the C plugin is a tag only)
    local infos = NONE
    local accesses
    if rawequal(fp_tvb, tvb) and fp_off == off then
        accesses = fp_accesses  -- worked out by the first pass of this call
    elseif is_request then
        accesses = adu_accesses(tvb, off, adu_len, fcb, true,
            parse_request_pdu(tvb, off + 7, adu_len - 7, fcb % 128))
    else
        accesses = adu_accesses(tvb, off, adu_len, fcb, false, rec[R_REQUEST] and request_of(rec))
    end
    local o = sparse_opts
    o.only, o.no_summary, o.experts, o.proto_in = sp.only, not cols, experts, root
    -- (the C plugin writes the Info text: the summaries as parts, info_parts)
    local as_parts = cols and append_info and true or false
    o.parts = as_parts and info_parts
    for i = 1, #accesses do
        local pieces = mapped(accesses[i], tvb, off)
        for j = 1, #pieces do
            local p = pieces[j]
            if p.length > 0 then
                local src, soff = piece_source(tvb, p)
                o.kind, o.offset, o.first, o.length = p.kind, soff, p.first, p.length
                o.swap, o.data = p.swap, p.data
                o.image_len = (p.kind == "input") and 64 or 224
                if as_parts and info_np > 0 then
                    info_np = info_np + 1
                    info_parts[info_np] = "; "
                end
                o.np = info_np
                local info = image.dissect(src, pinfo, tree, o)
                if as_parts then
                    info_np = info.np
                elseif cols then
                    if infos == NONE then infos = {} end
                    infos[#infos + 1] = info.label or (p.kind .. " " .. info.summary)
                end
                if cols and info.tags ~= "" then
                    if infos == NONE then infos = {} end
                    infos.tags = (infos.tags or "") .. info.tags
                end
            end
        end
    end
    o.data = false
    return infos
end

-- An ADU in a sparse view (sp: sparse_plan()): the referenced facts flat
-- under the caller's tree, its images, the expert info when it is looked
-- at, the Info tags with the columns. Returns the Info parts (NONE:
-- nothing) and the poll gap to tag.
local function show_sparse(tvb, pinfo, tree, off, adu_len, rec, is_request, fcb, sp)
    -- (a tap that walks the tree's top level, -z io,phs, counts the protocol)
    local root = sp.protos and add(tree, proto, tvb(off, adu_len))
    local adders = sp.adders
    if #adders > 0 then
        local c = sparse_ctx
        c.rec, c.tree, c.pinfo, c.is_request = rec, tree, pinfo, is_request
        for i = 1, #adders do adders[i](c) end
        c.rec, c.tree, c.pinfo = false, false, false
    end
    local experts = sp.experts
    if experts and rec.no_request then tree:add_proto_expert_info(ef.no_request, NO_REQUEST_TEXT) end
    local infos = sparse_images(tvb, pinfo, tree, off, adu_len, rec, is_request, fcb, sp, root)
    if experts and rec.findings then
        local visited = p_visited(pinfo)
        for _, fd in ipairs(rec.findings) do
            local ex, text = handshake.shown(fd, visited)
            if ex then tree:add_proto_expert_info(ex, text) end
        end
    end
    if not sp.cols then return infos, false end
    local tags = adu_tags(rec, pinfo)
    if tags ~= "" then
        if infos == NONE then infos = {} end
        infos.tags = (infos.tags or "") .. tags
    end
    return infos, rec.poll_gap
end

-- The full tree's images of an ADU, under its item; returns their Info
-- parts.
local function tree_images(tvb, pinfo, item, off, adu_len, fcb, is_request, r)
    local infos = {}
    for _, a in ipairs(adu_accesses(tvb, off, adu_len, fcb, is_request, r)) do
        for _, p in ipairs(mapped(a, tvb, off)) do
            if p.length > 0 then
                local src, soff = piece_source(tvb, p)
                local label = string.format("(%s %d-%d%s)", TABLE_NAMES[a.tname]:lower(), p.addr_lo, p.addr_hi,
                    a.write and ", written" or "")
                local info = image.dissect(src, pinfo, item, { kind = p.kind, offset = soff, first = p.first,
                    length = p.length, swap = p.swap, label = label, data = p.data,
                    image_len = (p.kind == "input") and 64 or 224 })
                iodata.decode_eclink(info, -- vrshark_io hook
                    { server = tostring(is_request and pinfo.dst or pinfo.src) }, pinfo) -- vrshark_io hook
                infos[#infos + 1] = p.kind .. " " .. info.summary
                if info.tags ~= "" then infos.tags = (infos.tags or "") .. info.tags end
            end
            if p.bitmask then
                for _, bt in ipairs(bit_text(p)) do
                    set_generated(add(item, pf.bits, tvb(off, adu_len), bt[2]))
                end
            end
        end
    end
    return infos
end

-- The full tree's ages, previous BU state and handshake links of an ADU.
local function tree_links(item, rec)
    if rec[R_PCI_AGE] then
        record.add_time(item, pf.pci_age, "Time since PCI changed", rec[R_PCI_AGE], nstime(rec[R_PCI_AGE]),
                        pf.pci_age_ms)
    end
    if rec[R_PCO_AGE] then
        record.add_time(item, pf.pco_age, "Time since PCO changed", rec[R_PCO_AGE], nstime(rec[R_PCO_AGE]),
                        pf.pco_age_ms)
    end
    if rec.bu_state_prev then set_generated(add(item, pf.bu_state_prev, rec.bu_state_prev)) end
    local l = rec.links or NONE
    if l ~= NONE then
        for _, name in ipairs(LINK_NAMES) do
            if l[name] then set_generated(add(item, pf[name], l[name])) end
        end
        for _, name in ipairs(LATENCY_NAMES) do
            local v = l[name]
            if v then set_generated(add(item, pf[name], nstime(v))) end
        end
    end
end

-- The reassembled periodic data an ADU completed, under its item.
local function tree_periodic(item, pinfo, rec, is_request)
    local ba = ByteArray.new(rec.periodic.data, true)
    local rtvb = ba:tvb("Reassembled periodic data")
    local pt = add(item, pf.periodic_data, rtvb())
    iodata.decode("periodic.to_ru", -- vrshark_io hook
        { server = tostring(is_request and pinfo.dst or pinfo.src) }, rtvb(), pt, pinfo) -- vrshark_io hook
    pt:set_generated()
    pt:add(pf.periodic_length, #rec.periodic.data):set_generated()
    for _, fr in ipairs(rec.periodic.frames) do
        pt:add(pf.periodic_block_in, fr):set_generated()
    end
end

-- An ADU in the full tree: its item with the table and range, the server,
-- the links, its images, the findings. Returns the Info parts and the poll
-- gap to tag.
local function show_tree(tvb, pinfo, tree, off, adu_len, rec, is_request, fcb)
    local fc = fcb % 128
    local r
    if is_request then
        r = parse_request_pdu(tvb, off + 7, adu_len - 7, fc)
    elseif rec[R_REQUEST] then
        r = request_of(rec)
    end
    local server = server_text(pinfo, is_request)
    local item = add(tree, proto, tvb(off, adu_len))
    local tname = FC_TABLE[fc]
    local desc = TABLE_NAMES[tname]
    if fc == 23 and is_request and r and r.wstart then
        -- the request decodes the image it writes: name that range
        desc = string.format("%s %d-%d (written)", desc, r.wstart, r.wstart + math.max(r.wcount, 1) - 1)
    elseif rec[R_START] then
        desc = string.format("%s %d-%d", desc, rec[R_START], rec[R_START] + math.max(rec[R_COUNT], 1) - 1)
    end
    append_text(item, ": " .. desc)
    set_generated(add(item, pf.table, tvb(off + 7, 1), desc))
    set_generated(add(item, pf.server, server))
    if rec[R_ACCEPTED] then set_generated(add(item, pf.accepted_in, rec[R_ACCEPTED])) end
    if rec[R_REQUEST] then
        set_generated(add(item, pf.request_in, rec[R_REQUEST]))
        set_generated(add(item, pf.time, nstime(rec[R_TIME])))
    end
    if rec[R_RESPONSE] then set_generated(add(item, pf.response_in, rec[R_RESPONSE])) end
    if rec.no_request then item:add_proto_expert_info(ef.no_request, NO_REQUEST_TEXT) end
    if rec.poll_gap then
        set_generated(add(item, pf.poll_gap_time, nstime(rec.poll_gap)))
        set_generated(add(item, pf.poll_gap_from, rec.poll_gap_from))
    end
    local infos = tree_images(tvb, pinfo, item, off, adu_len, fcb, is_request, r)
    tree_links(item, rec)
    for _, fd in ipairs(rec.findings or NONE) do
        local ex, text = handshake.shown(fd, pinfo.visited)
        if ex then
            item:add_proto_expert_info(ex, text)
            if LCD[ex] then set_generated(add(item, image.fields.lcd, LCD[ex])) end
        end
    end
    local tags = adu_tags(rec, pinfo)
    if tags ~= "" then infos.tags = (infos.tags or "") .. tags end
    if rec.periodic then tree_periodic(item, pinfo, rec, is_request) end
    if opt.assembled then
        show_assembled(item, pinfo, rec.snap_in, "input")
        show_assembled(item, pinfo, rec.snap_out, "output")
    end
    return infos, rec.poll_gap
end

------------------------------------------------------------------------
-- A BU's server on a TCP port nobody reads as Modbus/TCP
------------------------------------------------------------------------
-- Its frames reach TCP's heuristics only (no port dissector took them). A
-- request whose MBAP headers fill the segment exactly and which reads a
-- whole input image or writes an output image (the accesses a BU's
-- evidence needs: modbus_detect.luam) gets the candidate note, with the
-- setting that decodes it: the ports already decoded with this one
-- (eclink_modbus.port:502,5020), under which the detection judges the
-- server (an ordinary IO device is polled the same way), once its
-- connection's requests could carry the evidence; before that (an excerpt
-- too short for the heuristic) the server with its port
-- (eclink_modbus.servers:ADDR:PORT), which decodes it from its first frame.
-- Worked out on the first pass and kept per frame: one pass and two agree.
-- With the C plugin its front end checks the same in C and calls hook
-- "port_hint"; without it this is a heuristic of TCP (vrshark/transport.luam
-- serve() registers either). Either way it is asked
-- before Wireshark's own TCP heuristics (rpcap takes some Modbus requests
-- for its own and fails on them). Off with detection off.
local function image_request(tvb)
    local n, off, shaped = tvb:len(), 0, false
    if n < 12 or n > 4096 then return false end
    local reads, writes = false, false
    while off < n do
        if off + 12 > n then return false end
        local _, _, p1, p2, l1, l2, _, fc = tvb:raw(off, 8):byte(1, 8)
        local adu = 6 + l1 * 256 + l2
        if p1 ~= 0 or p2 ~= 0 or adu < 12 or off + adu > n then return false end
        -- the heuristic's own tests (look()): a whole input image read, the output image written
        local tname = FC_TABLE[fc]
        local r = tname and parse_request_pdu(tvb, off + 7, adu - 7, fc)
        if r and READS[fc] and r.count and full_input(tname, r.start, r.count) then
            shaped, reads = true, true
        end
        if r and r.wstart and full_output_write({ write = true, tname = tname, start = r.wstart,
                                                   count = r.wcount }) then
            shaped, writes = true, true
        end
        off = off + adu
    end
    return shaped, reads, writes
end

local data_dissector = Dissector.get("data")

-- The setting a request's note names, worked out on the first pass (kept
-- per frame: two passes agree): the ports already decoded with this one
-- (the detection then judges the server, as on 502) once the connection's
-- requests could carry the evidence (detect.requests), else, for an
-- excerpt too short for the heuristic, the server with its port (decoded
-- from its first frame; the entries already listed kept).
local function hint_setting(pinfo, port, reads, writes)
    local n = p_number(pinfo)
    if p_visited(pinfo) and hint_of[n] then return hint_of[n], hint_short[n] end
    local key = conn_key(pinfo, true, pinfo.src_port, port)
    local reqs = hint_conns[key]
    if not reqs then
        reqs = {}
        hint_conns[key] = reqs
    end
    local t, enough = p_abs_ts(pinfo), false
    if writes then enough = detect.requests(reqs, "write", t) end
    if reads then enough = detect.requests(reqs, "read", t) end
    local addr = tostring(pinfo.dst)
    local setting
    if enough or not servers.ipv4(addr) then
        setting = "eclink_modbus.port:" .. ports.with(proto.prefs.port, port)
    else
        setting = servers.setting(addr, port, proto.prefs.servers, true)
    end
    hint_of[n], hint_short[n] = setting, not enough
    return setting, not enough
end

local function port_hint(tvb, pinfo, tree)
    if opt.detection == DETECT_OFF then return 0 end
    local shaped, reads, writes = image_request(tvb)
    if not shaped then return 0 end
    local port = pinfo.dst_port
    -- (a port some dissector sits on had its turn, or has it next: TCP's
    -- "try heuristic sub-dissectors first")
    if tcp_port_table:get_dissector(port) then return 0 end
    local setting, short = hint_setting(pinfo, port, reads, writes)
    data_dissector:call(tvb, pinfo, tree)
    local item = add(tree, pf.candidate_setting, tvb(), setting)
    item:set_generated()
    item:add_proto_expert_info(ef.candidate, string.format("Looks like a request to a BU's Modbus/TCP server "
        .. "(an image access) on TCP port %d, which is not read as Modbus/TCP: not decoded%s; to decode it: %s",
        port, short and ", too few requests yet for the heuristic" or "", setting))
    pinfo.cols.protocol = "Modbus/TCP?"
    pinfo.cols.info = string.format("Modbus/TCP request? to port %d, which is not read as Modbus/TCP "
        .. "[to decode: %s]", port, setting)
    return tvb:len()
end

-- Whether this plugin decodes the connection of a frame as its first pass
-- stands: every connection ("always"), a listed server, one accepted.
local function decodes(pinfo, is_request, src_port, dst_port)
    if opt.detection == DETECT_ALWAYS then return true end
    local c = conns[conn_key(pinfo, is_request, src_port, dst_port)]
    if c and c.pinned ~= nil then
        return c.pinned or (opt.detection == DETECT_HEURISTIC and c.accepted ~= nil)
    end
    local port = is_request and dst_port or src_port
    return opt.any_servers and servers.listed(opt.servers, tostring(is_request and p_dst(pinfo) or p_src(pinfo)),
        port, p_match_uint(pinfo)) or false
end

-- The first bytes of a BU's response alone in a segment, fewer than the 8
-- that mbtcp needs to take it (it never asks TCP for the rest, and the
-- response would be lost, in order or not): how many more bytes make the
-- ADU (DESEGMENT_ONE_MORE_SEGMENT while its length is not in), for TCP to
-- join them; false unless they are the head of the response to a pending
-- request of a connection decoded (its transaction id, and its length where
-- it is in: data from inside an ADU that looks like a head is noted instead).
local RESPONSE_FIXED = { [5] = 6, [6] = 6, [15] = 6, [16] = 6 }
local function head_more(tvb, pinfo, is_request, src_port, dst_port)
    local n = tvb_len(tvb)
    if is_request or n < 2 or tvb_reported_len(tvb) ~= n or p_visited(pinfo) then return false end
    local t1, t2, p1, p2, l1, l2 = tvb_raw(tvb, 0, n):byte(1, n)
    if (p1 or 0) ~= 0 or (p2 or 0) ~= 0 or not decodes(pinfo, false, src_port, dst_port) then return false end
    local c = conns[conn_key(pinfo, false, src_port, dst_port)]
    local plen = l2 and l1 * 256 + l2
    for tkey, r in pairs(c and c.pending or NONE) do
        if math.floor(tkey / 65536) == t1 * 256 + t2 then
            local fc = tkey % 256
            local want = RESPONSE_FIXED[fc] or (fc <= 2 and 3 + math.ceil((r.count or 0) / 8))
                or 3 + 2 * (r.count or 0)
            if not plen then return DESEGMENT_ONE_MORE_SEGMENT end
            if plen == want or plen == 3 then return 6 + plen - n end  -- (3: an exception)
        end
    end
    return false
end

-- A buffer that does not start with an MBAP header, on a connection this
-- plugin decodes: TCP handed over the bytes after a gap in the sequence
-- (segments out of order with Wireshark's default, or not captured), and
-- the ADU they belong to reaches neither Modbus/TCP nor EC-Link. The note
-- text, or false; worked out on the first pass, kept per frame and buffer
-- (one pass and two agree).
local function mid_adu_note(tvb, pinfo, is_request, src_port, dst_port, n, rl)
    local _, _, p1, p2, l1, l2 = tvb_raw(tvb, 0, 6):byte(1, 6)
    if p1 == 0 and p2 == 0 and l1 * 256 + l2 >= 2 then return false end  -- (an ADU, cut or whole)
    local key = p_number(pinfo) .. ":" .. rl
    local note = mid_adu_of[key]
    if note == nil and not p_visited(pinfo) then
        note = decodes(pinfo, is_request, src_port, dst_port)
            and string.format(MID_ADU_TEXT, n, is_request and "controller" or "BU") or false
        mid_adu_of[key] = note
    end
    return note
end

-- The note on an ADU of a connection with a BU's shape, not accepted: the
-- setting in a field of its own, on the parent tree (the protocol item
-- stays for decoded ADUs: "eclink_modbus" keeps matching those alone).
local function show_hint(tvb, tree, off, adu_len, rec)
    local item = tree:add(pf.candidate_setting, tvb(off, adu_len), rec.hint_setting)
    item:set_generated()
    item:add_proto_expert_info(ef.candidate, rec.hint)
end

------------------------------------------------------------------------
-- The dissector: the EC-Link view of each complete ADU, mbtcp run first
------------------------------------------------------------------------
-- dissect() is the one entry point, whatever calls it (vrshark/transport.luam
-- serve() says who): the C front end with its view (seam.luam view():
-- ".quiet": nobody looks at this frame's tree or columns, only the state is
-- kept; ".sparse:..." an invisible tree, sparse_plan()) and whether the
-- connection is accepted (non-zero back: yes), or TCP, through the
-- transport that ran mbtcp in Lua (no C plugin, or Decode As).

-- The ADUs of a buffer (offset, length, record, function code byte, flat,
-- each), one array used again by every call: the ADUs are worked out before
-- any is shown, and nothing shown calls this dissector again.
local found_scratch = {}

-- tshark -2 -R: a dropped frame's records under this number, forgotten
-- once per frame.
local function forget_dropped(number, visited)
    if passes.stale("eclink_modbus", number, visited) and number == top_n then
        for i = 1, #top_keys do adus[top_keys[i]] = nil end
        top_keys = {}
    end
end

-- Each complete ADU of the buffer worked out (its record loaded, or made by
-- the first pass) into found_scratch; returns how many slots it filled.
local function work_out(tvb, pinfo, n, number, rl, is_request, via_front, src_port, dst_port)
    local found, nf, off = found_scratch, 0, 0
    while off + 8 <= n do
        local t1, t2, p1, p2, l1, l2, unit, fcb = tvb_raw(tvb, off, 8):byte(1, 8)
        local plen = l1 * 256 + l2
        if p1 ~= 0 or p2 ~= 0 or plen < 2 then break end
        local adu_len = 6 + plen
        if off + adu_len > n then break end
        -- one entry per ADU: a number key (frame, length of the buffer) for the
        -- usual first ADU of a buffer, a string key for the others
        local key
        if off == 0 and rl < 1048576 then
            key = rl * 4294967296 + number
        else
            key = number .. ":" .. rl .. ":" .. off
        end
        local rec, done = load_rec(key, number, rl, off, is_request)
        -- (the C front end hands a candidate's later frames over again for
        -- the notes: one the first pass did not see stays Modbus's)
        if not rec and via_front and p_visited(pinfo) then rec = NOT_DECODED end
        if not rec then
            rec = first_pass(tvb, pinfo, off, adu_len, is_request, t1 * 256 + t2, unit, fcb, number, src_port, dst_port)
            done = store_rec(key, number, rl, off, rec, is_request)
        end
        -- done: a flat record's table, free once shown
        found[nf + 1], found[nf + 2], found[nf + 3], found[nf + 4], found[nf + 5] = off, adu_len, rec, fcb, done
        nf = nf + 5
        off = off + adu_len
    end
    return nf
end

-- The ADUs worked out, shown after all of the buffer's are: one that
-- recognizes the connection shows the earlier ones of its frame too, in one
-- pass as in two. Returns whether one was decoded, the Info parts of their
-- images (NONE: nothing to show) and the poll gaps' tags (nil: none).
local function show_found(tvb, pinfo, tree, nf, view, quiet, is_request)
    local found = found_scratch
    local decoded, infos, gaps = false, nil, nil
    -- (made at the first ADU shown; false: the full tree. Without the C
    -- front end the view is made from what is referenced: transport.lua_view())
    local sp
    for i = 1, nf, 5 do
        local f_off, f_len, rec, f_fcb = found[i], found[i + 1], found[i + 2], found[i + 3]
        found[i + 2] = false
        -- a candidate's ADU is shown once the connection is accepted
        local shown = rec ~= NOT_DECODED and (rec[R_ACCEPTED] or not rec.pending)
        if shown and quiet then
            decoded = true
        elseif shown then
            decoded = true
            if sp == nil then sp = sparse_plan(view or lua_view(tree, pinfo)) or false end
            local adu_infos, gap
            if sp then
                adu_infos, gap = show_sparse(tvb, pinfo, tree, f_off, f_len, rec, is_request, f_fcb, sp)
            else
                adu_infos, gap = show_tree(tvb, pinfo, tree, f_off, f_len, rec, is_request, f_fcb)
            end
            if not infos or infos == NONE then
                infos = adu_infos  -- (the usual buffer: one ADU; NONE: nothing to show)
            elseif adu_infos ~= NONE then
                for _, s in ipairs(adu_infos) do infos[#infos + 1] = s end
                if adu_infos.tags then infos.tags = (infos.tags or "") .. adu_infos.tags end
            end
            if gap then
                gaps = gaps or {}
                gaps[#gaps + 1] = string.format(" [poll gap %.3f s]", gap)
            end
        elseif rec.hint and not rec[R_ACCEPTED] and not quiet then
            show_hint(tvb, tree, f_off, f_len, rec)
        end
        if found[i + 4] then spare_rec = rec end
    end
    return decoded, infos or NONE, gaps
end

-- A buffer with no complete ADU: the head of a BU's response that TCP is
-- to join with the next segment (true: asked for), or data from inside an
-- ADU, noted.
local function no_adu(tvb, pinfo, tree, n, rl, view, quiet, is_request, src_port, dst_port)
    if n < 8 and pinfo.can_desegment > 0 and pinfo.desegment_len == 0 then
        local more = head_more(tvb, pinfo, is_request, src_port, dst_port)
        if more then
            pinfo.desegment_offset, pinfo.desegment_len = 0, more
            return true
        end
    end
    if n < 6 then return false end
    local note = mid_adu_note(tvb, pinfo, is_request, src_port, dst_port, n, rl)
    if note and not quiet then
        local sp = sparse_plan(view or lua_view(tree, pinfo)) or false
        -- (under the protocol's item, as a tree shows it; the bytes stay Data)
        local item = (not sp or sp.protos) and add(tree, proto, tvb())
        if item then append_text(item, ": TCP data from inside an ADU, not decoded") end
        set_generated(add(item or tree, pf.server, server_text(pinfo, is_request)))
        if not sp or sp.experts then (item or tree):add_proto_expert_info(ef.mid_adu, note) end
        if not sp or sp.cols then pinfo.cols.info:append(" [EC-Link ADU not decoded]") end
    end
    return false
end

-- The frame's Info: the tags first (after Modbus's own long text they stay
-- in view in a packet list column that cannot show the whole image summary
-- too), then the images' summaries.
local function write_info(pinfo, infos, gaps)
    local tags = infos.tags or ""
    if gaps then tags = tags .. table.concat(gaps) end
    if info_np > 0 then
        -- (the C plugin joins the parts: no new string, no column objects)
        info_parts[info_np + 1] = "]"
        if not append_info(tags, " [EC-Link ", unpack(info_parts, 1, info_np + 1)) then
            pinfo.cols.info:append(tags .. " [EC-Link " .. table.concat(info_parts, "", 1, info_np + 1))
        end
    elseif #infos > 0 then
        pinfo.cols.info:append(tags .. " [EC-Link " .. table.concat(infos, "; ") .. "]")
    elseif tags ~= "" then
        pinfo.cols.info:append(tags)
    end
end

-- view: what is looked at (false: not sent: the whole tree, or made from
-- the tree, lua_view()); via_front: the C front end picked this frame;
-- consumed: what mbtcp took.
local function dissect(tvb, pinfo, tree, view, via_front, consumed, src_port, dst_port, is_request)
    if opt.detection == DETECT_OFF and not opt.any_servers then return consumed end
    info_np = 0
    local quiet = view and view.quiet
    local n, number, rl = tvb_len(tvb), p_number(pinfo), tvb_reported_len(tvb)
    if renumbers then forget_dropped(number, p_visited(pinfo)) end
    local nf = work_out(tvb, pinfo, n, number, rl, is_request, via_front, src_port, dst_port)
    if nf == 0 then
        if no_adu(tvb, pinfo, tree, n, rl, view, quiet, is_request, src_port, dst_port) then return n end
        return consumed
    end
    local decoded, infos, gaps = show_found(tvb, pinfo, tree, nf, view, quiet, is_request)
    -- (nothing to write on most frames of a connection not a BU's)
    if info_np > 0 or gaps or infos ~= NONE then write_info(pinfo, infos, gaps) end
    if via_front and decoded then return n end
    return consumed
end

-- (every Modbus/TCP frame the decoder sees is a tick of the shared clock,
-- after its own analysis armed its streams and its own items are shown:
-- the transport's entry point ticks after dissect())
transport.serve(dissect, port_hint, prefs_changed)
