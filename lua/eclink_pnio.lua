--[[ eclink_pnio.lua -- EC-Link images (TS-0007) in PROFINET IO cyclic data
(protocol "eclink_pnio").

The carrier (vrshark_pnio.lua) finds the frames and their layout; this file
decodes the images and supervises the handshake. The BU's submodules:

  slot 1 "Inputs"            64 bytes, input CR (BU -> controller)
  slot 2 "Command Outputs"   20 bytes, or "Standard Outputs" 224 bytes, output CR
         (no slot 2 on an "Input Only" BU)

each followed by its IOPS; the IOCS of the other direction sit at their own
offsets. The images are decoded by vrshark/eclink_image.luam (the fields of
protocol "eclink", the same as over Modbus/TCP); the handshake counters (PCI,
PCO, CCI -> CAO, CCO -> CAI, BU state) are supervised by
vrshark/eclink_handshake.luam with the same rules and messages as over
Modbus/TCP, on the first pass in frame order, per device, and stored in the
frame's record, so tshark -2 and clicking around show the same as one pass.
]]

local dir = debug.getinfo(1, "S").source:match("^@(.*)[/\\]")
package.path = dir .. "/?.luam;" .. package.path
set_plugin_info(require("vrshark.version").info("EC-Link images (TS-0007) in PROFINET IO cyclic data"))
local eclink_handshake = require("vrshark.eclink_handshake")
local image = require("vrshark.eclink_image")
local periodic = require("vrshark.eclink_periodic")
local record = require("vrshark.pnio_record")
local health = require("vrshark.health") -- Statistics > EC-Link
local systems = require("vrshark.pnio_systems")
local iodata = require("vrshark.iodata") -- vrshark_io hook
local fe = require("vrshark.frontends")
local set_cols = fe.set_cols
local unpack = table.unpack or unpack  -- luacheck: ignore 113 (Lua 5.1/5.2 global)
-- the Info text of the sparse view as parts (image.dissect opts.parts), for set_cols()
local info_parts = {}
image.proto()  -- the single Proto("eclink"), shared with the other EC-Link plugins

local add_finding, attach = record.add_finding, record.attach
local byte = string.byte
-- (methods called as functions on the per-frame paths: vrshark/api.luam says why)
local api = require("vrshark.api")
local add, range, set_generated = api.add, api.range, api.set_generated
local p_number = api.pinfo.number

local eclp = Proto("eclink_pnio", "EC-Link over PROFINET IO")
eclp.prefs.cai_timeout = Pref.uint("CAI timeout (ms)", 2000,
    "A command to the RU (a new CCO) that CAI does not echo within this is a warning. TS-0007 8.2 gives no "
    .. "time: the limit is this project's own, by default the 2000 ms that 8.1 gives CAO")

------------------------------------------------------------------------
-- Fields and experts
------------------------------------------------------------------------
local epf = {
    pci_age = ProtoField.relative_time("eclink_pnio.pci_age", "Time since PCI changed"),
    pco_age = ProtoField.relative_time("eclink_pnio.pco_age", "Time since PCO changed"),
    pci_age_ms = ProtoField.uint32("eclink_pnio.pci_age_ms", "Time since PCI changed (ms)"),
    pco_age_ms = ProtoField.uint32("eclink_pnio.pco_age_ms", "Time since PCO changed (ms)"),
    layout = ProtoField.string("eclink_pnio.layout", "Layout from"),
    frame_id = ProtoField.uint16("eclink_pnio.frame_id", "FrameID", base.HEX),
    layout_entry = ProtoField.string("eclink_pnio.layout_entry", "Layout table entry (to pin it: mcmb2.layouts)"),
    iops = ProtoField.uint8("eclink_pnio.iops", "IOPS", base.HEX, record.IOXS),
    iocs = ProtoField.uint8("eclink_pnio.iocs", "IOCS", base.HEX, record.IOXS),
    -- periodic output blocks (TS-0007 section 8.4), as over Modbus/TCP
    periodic_reassembled_in = ProtoField.framenum("eclink_pnio.periodic.reassembled_in",
        "Periodic data reassembled in"),
    periodic_block_in = ProtoField.framenum("eclink_pnio.periodic.block_in", "Periodic data block in"),
    periodic_length = ProtoField.uint32("eclink_pnio.periodic.length", "Reassembled periodic data length"),
    periodic_data = ProtoField.bytes("eclink_pnio.periodic.data", "Reassembled periodic data"),
    -- a stream that stops, and the PROFINET cycle (vrshark/pnio_stops.luam)
    missing_since = ProtoField.framenum("eclink_pnio.missing_since", "Last frame of the stream"),
    missing_time = ProtoField.relative_time("eclink_pnio.missing_time", "No frame of the stream for"),
    lost_frames = ProtoField.uint32("eclink_pnio.lost_frames", "Frames lost (cycle counter)", base.DEC),
}
-- frame links of the handshake findings and acknowledgements
local hs_fields, hs_field_list = eclink_handshake.fields("eclink_pnio")
for _, f in pairs(epf) do hs_field_list[#hs_field_list + 1] = f end
eclp.fields = hs_field_list
-- the handshake experts (same wording as over Modbus/TCP) come from vrshark.eclink_handshake
local eef, eclp_experts = eclink_handshake.experts("eclink_pnio")
eef.iops_bad = ProtoExpert.new("eclink_pnio.iops.bad", "IOPS is not GOOD (0x80)", expert.group.PROTOCOL,
    expert.severity.WARN)
eef.short = ProtoExpert.new("eclink_pnio.short", "C-SDU shorter than the layout", expert.group.MALFORMED,
    expert.severity.ERROR)
eef.cut = ProtoExpert.new("eclink_pnio.cut", "Frame cut by the capture (snaplen): only the bytes captured are decoded",
    expert.group.MALFORMED, expert.severity.NOTE)
eef.learned = ProtoExpert.new("eclink_pnio.layout.learned", "Cyclic data layout learned from this Connect",
    expert.group.SEQUENCE, expert.severity.CHAT)
eef.inferred = ProtoExpert.new("eclink_pnio.layout.inferred", "Cyclic data layout inferred from the cyclic frames",
    expert.group.SEQUENCE, expert.severity.NOTE)
eef.reopened = ProtoExpert.new("eclink_pnio.layout.reopened",
    "Cyclic data layout inferred from the cyclic frames contradicted: the inference is re-opened",
    expert.group.SEQUENCE, expert.severity.WARN)
eef.pn_malformed = ProtoExpert.new("eclink_pnio.pn_malformed",
    "Malformed to Wireshark's PROFINET dissector, but the layout fits the frame: decoded",
    expert.group.PROTOCOL, expert.severity.NOTE)
eef.periodic_reassembled = ProtoExpert.new("eclink_pnio.periodic.reassembled", "Periodic data reassembled",
    expert.group.REASSEMBLE, expert.severity.CHAT)
-- a stream that stops, and the PROFINET cycle (vrshark/pnio_stops.luam)
for _, e in ipairs({
    { "input_missing", "No input frame for over 500 ms: PCI cannot move, bring the system to a safe state "
        .. "(TS-0007 8.3)", "ERROR" },
    { "output_missing", "No output frame for over 2000 ms: PCO cannot move, the BU indicates an error (TS-0007 8.4)",
        "ERROR" },
    { "data_hold_exceeded", "No frame of the stream within the data hold time of the Connect's IOCR: the AR is "
        .. "aborted", "ERROR" },
    { "frames_lost", "Cyclic frames lost (gap in the PN-RT cycle counter)", "WARN" } }) do
    eef[e[1]] = ProtoExpert.new("eclink_pnio." .. e[1], e[2], expert.group.SEQUENCE, expert.severity[e[3]])
end
for _, k in ipairs({ "iops_bad", "short", "learned", "inferred", "reopened", "pn_malformed", "cut",
                    "periodic_reassembled", "input_missing", "output_missing", "data_hold_exceeded",
                    "frames_lost" }) do
    eclp_experts[#eclp_experts + 1] = eef[k]
end
eclp.experts = eclp_experts
-- the BU display text beside the findings that cause it (TS-0007 9): eclink.lcd
for ex, text in pairs(eclink_handshake.lcd_by_expert(eef)) do record.beside[ex] = { image.fields.lcd, text } end

------------------------------------------------------------------------
-- Per-capture state
------------------------------------------------------------------------
local devs -- device key (plan.dev) -> handshake state
local periodics -- device key -> periodic output blocks (vrshark/eclink_periodic.luam)
-- frame of a block -> frame that completed its periodic data. By frame
-- number, not on the block's record: the carrier shares and reuses records
-- that have no finding.
local periodic_in

function eclp.init()
    devs, periodics, periodic_in = {}, {}, {}
end

-- The handshake's links to a command's frame, kept on the record.
local CMD_LINKS = { "cmd_from_ru_in", "cmd_to_ru_in" }

------------------------------------------------------------------------
-- First pass
------------------------------------------------------------------------
-- The image values handed to the handshake, one table each direction
-- filled anew for every frame (the handshake reads them at once).
local in_values, out_values = {}, {}

-- The periodic output blocks of a standard output image (224 bytes):
-- every cycle repeats the image, a block counts once per PCO. The frame
-- that completes the data keeps it (with a finding: its record is kept).
local function periodic_blocks(dev, rec, ba, o, pco, frame)
    local s1, s2, block = byte(ba, o + 21, o + 23)
    local size = s1 * 256 + s2
    local blen = periodic.block_len(size, block)
    local st = periodics[dev]
    if not st then
        st = {}
        periodics[dev] = st
    end
    local got = periodic.add(st, size, block, pco, blen and ba:sub(o + 25, o + 24 + blen), frame, rec)
    if type(got) ~= "table" then return end
    for _, f in ipairs(got.frames) do
        if f ~= frame then periodic_in[f] = frame end
    end
    rec.periodic = { data = got.data, frames = got.frames }
    add_finding(rec, "image", eef.periodic_reassembled, string.format(
        "Periodic data reassembled: %d bytes from %d blocks", got.size, got.n))
end

-- ba: the C-SDU as a Lua string (byte i at byte(ba, i + 1)).
local function analyse(rec, ba, t, frame)
    local plan = rec.plan
    local hs = devs[plan.dev]
    if not hs then
        hs = eclink_handshake.new(eclp.prefs.cai_timeout / 1000)
        devs[plan.dev] = hs
    end
    local o = plan.image.off
    -- (a frame the capture cut: only the counters captured are read, a
    -- byte not captured reads nil and is no value)
    local partial = record.partial(rec)
    if not partial then record.check_ioxs(rec, ba, eef.iops_bad, nil) end
    local inp, out
    if plan.dir == "up" then
        local pci, cci, _, cai = byte(ba, o + 1, o + 4)
        inp = in_values
        inp.pci, inp.cci, inp.cai, inp.bu = pci, cci, cai, byte(ba, o + 21)
    else
        local pco, cco, _, cao = byte(ba, o + 1, o + 4)
        out = out_values
        out.pco, out.cco, out.cao, out.len = pco, cco, cao, plan.image.len
    end
    -- (the rules go by a time that never runs backwards: a clock step is a finding)
    local step
    t, step = eclink_handshake.clock(hs, t, frame, "the PCI, PCO and command deadline rules")
    if step then add_finding(rec, "image", eef.time_backwards, step[2]) end
    local r = eclink_handshake.update(hs, inp, out, t, frame, rec)
    local links
    for _, f in ipairs(r.findings) do
        -- a finding that reads otherwise in one pass: placed when shown
        if f.once then
            rec.passing = rec.passing or {}
            rec.passing[#rec.passing + 1] = { eef[f[1]] or false, f[2], once = { eef[f.once[1]], f.once[2] } }
        else
            add_finding(rec, "image", eef[f[1]], f[2])
        end
        if f[1] and f[1]:find("_late_ack$") then rec.late_ack = true end
        if f[3] then
            links = links or {}
            links[#links + 1] = { f[3], f[4] }
        end
    end
    for _, name in ipairs(CMD_LINKS) do
        if r.links[name] then
            links = links or {}
            links[#links + 1] = { name, r.links[name] }
        end
    end
    rec.links = links
    -- the command frame of a missed deadline: its finding and the link to
    -- the frame that saw the deadline pass (shown on the second pass)
    for _, b in ipairs(r.back) do
        local cmd = b[1]
        if cmd and b[4] then
            add_finding(cmd, "image", eef[b[4][1]], b[4][2])
            health.pnio_finding(cmd.plan, eef[b[4][1]])
            cmd.unacked = true
            cmd.links = cmd.links or {}
            cmd.links[#cmd.links + 1] = { b[2], b[3] }
        end
    end
    rec.pci_age = r.pci_age and eclink_handshake.ms(r.pci_age)
    rec.pco_age = r.pco_age and eclink_handshake.ms(r.pco_age)
    if out and not partial and plan.image.len > 24 then periodic_blocks(plan.dev, rec, ba, o, out.pco, frame) end
end

------------------------------------------------------------------------
-- Display
------------------------------------------------------------------------
-- The reassembled periodic data (on the frame of the last block) or the
-- link to it (on the other blocks' frames), as over Modbus/TCP.
local function show_periodic(rec, root, pinfo, fid)
    local done = periodic_in[pinfo.number]
    if done then set_generated(add(root, epf.periodic_reassembled_in, done)) end
    local p = rec.periodic
    if not p then return end
    local rtvb = ByteArray.new(p.data, true):tvb("Reassembled periodic data")
    local pt = add(root, epf.periodic_data, rtvb())
    iodata.decode("periodic.to_ru", { frame_id = fid }, rtvb(), pt, pinfo) -- vrshark_io hook
    set_generated(pt)
    set_generated(add(pt, epf.periodic_length, #p.data))
    for _, fr in ipairs(p.frames) do set_generated(add(pt, epf.periodic_block_in, fr)) end
end

local function show(rec, tvb, pinfo, tree)
    local plan, base = rec.plan, rec.base
    local up = plan.dir == "up"
    local root = record.root(rec, tvb, tree, eclp, up and ", input image" or ", output image")
    set_generated(add(root, epf.layout, plan.source))
    if plan.entry then set_generated(add(root, epf.layout_entry, plan.entry)) end
    add(root, epf.frame_id, range(tvb, 0, 2))
    attach(rec, "top", root)
    local cols = pinfo.cols -- (each pinfo.cols makes a Columns object)
    cols.protocol = "EC-Link"
    if rec.size < plan.need then
        cols.info = "EC-Link: C-SDU too short for the layout"
        return root
    end
    local o = plan.image
    -- (a frame the capture cut: the image bytes captured)
    local partial = record.partial(rec)
    local len = partial and math.max(0, math.min(o.len, rec.cut - o.off)) or o.len
    local info = len > 0 and image.dissect(tvb, pinfo, root, { kind = up and "input" or "output",
        offset = base + o.off, length = len, image_len = o.len })
    if info and next(iodata.areas) then -- vrshark_io hook
        iodata.decode_eclink(info, { frame_id = tvb(0, 2):uint() }, pinfo) -- vrshark_io hook
    end -- vrshark_io hook
    if rec.pci_age then
        record.add_time(root, epf.pci_age, "Time since PCI changed", rec.pci_age, nil, epf.pci_age_ms)
    end
    if rec.pco_age then
        record.add_time(root, epf.pco_age, "Time since PCO changed", rec.pco_age, nil, epf.pco_age_ms)
    end
    for _, l in ipairs(rec.links or {}) do root:add(hs_fields[l[1]], l[2]):set_generated() end
    show_periodic(rec, root, pinfo, tvb(0, 2):uint())
    attach(rec, "image", info and info.item or root)
    -- a command's deadline: in one pass the command's warning, else a note;
    -- [unacked] either way (a live packet list draws the row once)
    local unacked = rec.unacked
    for _, f in ipairs(rec.passing or {}) do
        local ex, text = eclink_handshake.shown(f, pinfo.visited)
        if ex then record.expert(info and info.item or root, ex, text) end
        if ex == eef.cmd_from_ru_late or ex == eef.cmd_to_ru_late or ex == eef.cmd_from_ru_deadline
                or ex == eef.cmd_to_ru_deadline then unacked = true end
    end
    if not partial then record.add_ioxs(root, rec, tvb, epf.iops, epf.iocs) end
    record.finish(rec, partial and root or nil)
    cols.info = (up and "Input image " or "Output image ") .. ((info and info.summary) or "")
        .. ((info and info.tags) or "") .. eclink_handshake.tags(rec.pci_age, rec.pco_age)
        .. (unacked and " [unacked]" or "") .. (rec.late_ack and " [late ack]" or "")
        .. (partial and string.format(" [cut by the capture: %d of %d C-SDU bytes]", rec.cut, rec.size) or "")
    return root
end

------------------------------------------------------------------------
-- Sparse display: an invisible tree (the packet list, -T fields, -Y)
------------------------------------------------------------------------
-- As in mcmb2.lua: only the referenced fields, flat, in the occurrences
-- show() gives them (tests/test_sparse_view.py), the expert info when it is
-- looked at (flat, in show()'s order), then the columns. The image adds its
-- own fields and findings (image.dissect, opts.only, opts.experts). A
-- referenced expert, or a field without an adder here, means show().
local function age_adders(field, ms_field, key)
    return function(c) if c.rec[key] then add(c.tree, field, record.nstime(c.rec[key])) end end,
        function(c) if c.rec[key] then add(c.tree, ms_field, record.whole_ms(c.rec[key])) end end
end
local ADDERS = {
    ["eclink_pnio.layout"] = function(c) add(c.tree, epf.layout, c.plan.source) end,
    ["eclink_pnio.layout_entry"] = function(c) if c.plan.entry then add(c.tree, epf.layout_entry, c.plan.entry) end end,
    ["eclink_pnio.frame_id"] = function(c) add(c.tree, epf.frame_id, range(c.tvb, 0, 2)) end,
    ["eclink_pnio.iops"] = function(c) record.add_ioxs_sparse(c.tree, c.rec, c.tvb, epf.iops, false) end,
    ["eclink_pnio.iocs"] = function(c) record.add_ioxs_sparse(c.tree, c.rec, c.tvb, epf.iocs, true) end,
}
ADDERS["eclink_pnio.pci_age"], ADDERS["eclink_pnio.pci_age_ms"] = age_adders(epf.pci_age, epf.pci_age_ms, "pci_age")
ADDERS["eclink_pnio.pco_age"], ADDERS["eclink_pnio.pco_age_ms"] = age_adders(epf.pco_age, epf.pco_age_ms, "pco_age")
image.own_fields(ADDERS, function() end)
-- no expert names: any referenced expert means the full tree
local SPARSE = { adders = ADDERS, experts = {}, prefixes = { "eclink_pnio", "eclink", "vrshark_io", "vrshark.io" } }

-- false: show() is needed instead. One context table and one table of the
-- image's options, refilled per frame (nobody keeps them).
local ctx, image_opts = {}, {}
local function sparse(rec, tvb, pinfo, tree, view)
    if rec.periodic or periodic_in[p_number(pinfo)] then return false end
    local plan = rec.plan
    local p = fe.plan(view, SPARSE)
    -- machine data can add findings and Info tags of its own
    if not p or rec.size < plan.need or rec.cut or ((p.cols or p.experts) and next(iodata.areas)) then
        return false
    end
    -- (a tap that walks the tree's top level, -z io,phs, counts the protocol)
    local root = p.protos and record.root(rec, tvb, tree, eclp, "")
    local experts = p.experts
    if experts then attach(rec, "top", tree) end
    if #p.adders > 0 then
        local c = ctx
        c.rec, c.tvb, c.tree, c.plan = rec, tvb, tree, plan
        local adders = p.adders
        for i = 1, #adders do adders[i](c) end
    end
    local up = plan.dir == "up"
    local o = plan.image
    local opts = image_opts
    opts.kind, opts.offset, opts.length, opts.image_len = up and "input" or "output", rec.base + o.off, o.len, o.len
    opts.only, opts.no_summary, opts.experts, opts.proto_in = view.fields, not p.cols, experts, root
    -- (the C plugin writes the Info text: the summary as parts)
    opts.parts, opts.np, opts.lead = p.cols and set_cols and info_parts, 0, up and "Input image " or "Output image "
    local info = image.dissect(tvb, pinfo, tree, opts)
    if experts and (rec.findings ~= record.NO_FINDINGS or rec.passing) then
        attach(rec, "image", tree)
        for _, f in ipairs(rec.passing or {}) do
            local ex, text = eclink_handshake.shown(f, pinfo.visited)
            if ex then record.expert(tree, ex, text) end
        end
        if rec.ioxs_bad then
            attach(rec, "iops", tree)
            attach(rec, "iocs", tree)
        end
        record.finish(rec, nil)
    end
    if p.cols then
        -- a command's deadline: [unacked] on every pass, as show()
        local unacked = rec.unacked
        if not unacked and rec.passing then
            for _, f in ipairs(rec.passing) do
                local ex = eclink_handshake.shown(f, pinfo.visited)
                if ex == eef.cmd_from_ru_late or ex == eef.cmd_to_ru_late or ex == eef.cmd_from_ru_deadline
                        or ex == eef.cmd_to_ru_deadline then unacked = true end
            end
        end
        local tail = eclink_handshake.tags(rec.pci_age, rec.pco_age)
        local unacked_tag, late_tag = unacked and " [unacked]" or "", rec.late_ack and " [late ack]" or ""
        if opts.parts then
            -- (through the C plugin when it calls: no new string, no column objects)
            local n = info.np
            info_parts[n + 1], info_parts[n + 2], info_parts[n + 3], info_parts[n + 4] =
                info.tags, tail, unacked_tag, late_tag
            if not set_cols("EC-Link", unpack(info_parts, 1, n + 4)) then
                local cols = pinfo.cols
                cols.protocol = "EC-Link"
                cols.info = table.concat(info_parts, "", 1, n + 4)
            end
        else
            local cols = pinfo.cols
            cols.protocol = "EC-Link"
            cols.info = (up and "Input image " or "Output image ") .. info.summary .. info.tags
                .. tail .. unacked_tag .. late_tag
        end
    end
    return true
end

local function show_connect(rec, tvb, tree, text)
    local _ = rec
    local item = tree:add(eclp, tvb:range(0, 0))
    item:append_text(": layout learned, " .. text)
    item:add_proto_expert_info(eef.learned, "Cyclic data layout learned: " .. text)
end

-- (its frames are shown through its own dissector: pnio_systems.through(),
-- or handed to it by the C front end, pnio_systems.set_entry())
eclp.dissector = systems.dissector_of(eclp)
local dec = { proto = eclp, short = eef.short, cut = eef.cut, inferred = eef.inferred,
                                 reopened = eef.reopened,
                                 pn_malformed = eef.pn_malformed,
                                 per_frame = { up = "pci_age", down = "pco_age" }, analyse = analyse,
                                 show = show, sparse = sparse,
                                 -- (the Protos of its fields: frontends.lua_view())
                                 lua_protos = { eclp, image.proto() },
                                 show_connect = show_connect }
-- The deadlines of its streams (TS-0007 8.3: PCI stops for 500 ms; 8.4: PCO
-- not incremented for 2000 ms), a frame that stops coming being a counter
-- that cannot move.
dec.stops = require("vrshark.pnio_stops").watcher({ proto = eclp, dec = dec,
    ef = { up = eef.input_missing, down = eef.output_missing, hold = eef.data_hold_exceeded, lost = eef.frames_lost },
    pf = { since = epf.missing_since, time = epf.missing_time, lost = epf.lost_frames },
    names = { up = "input", down = "output" }, limits = { up = 0.5, down = 2 },
    texts = { up = "PCI cannot move, bring the system to a safe state (TS-0007 8.3)",
              down = "PCO cannot move, the BU indicates an error and opens the ES-Link relays if an RU is armed "
                  .. "(TS-0007 8.4)" } })
systems.register({ "eclink" }, dec)
