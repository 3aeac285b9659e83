--[[ vrshark/eclink_image.lua -- the EC-Link process images (protocol "eclink").

A shared module, not a plugin: loading it only builds and returns a table.
Plugins that carry EC-Link images (Modbus/TCP, PROFINET IO) require it and
call image.proto() once while they load; that creates the single
Proto("eclink") with every eclink.* field and expert, and registers the
dissector "eclink" that decodes a raw image (for a user link-layer type).

Images (integers big-endian inside the image):

  Input image, 64 bytes, BU -> machine controller
    0 PCI  1 CCI  2 PAI  3 CAI  4..19 command from RU (16)
   20 BU state  21 VLAPs  22 unarmed RUs  23 EG-Link  24 EC-Link  25 C-Link status
   26..27 armed RU (u16)  28 RU state  29 RU battery %  30 RU C-Link RSSI %
   31 RU cable  32 RU docked  33 RU disabled  34..41 joystick 1..4 (s16)
   42..57 switch 1..8 (s16)  58 encoder  59 encoder switch  60..63 spare (0)

  Output image, 20 bytes (Input + Commands) or 224 bytes (Standard)
    0 PCO  1 CCO  2 PAO  3 CAO  4..19 command to RU (16)
   20..21 periodic data size (u16, <= 51200)  22 periodic data block
   23 spare (0)  24..223 periodic data (200)

API
  image.proto()              -> the Proto("eclink"), created on the first call
                                (call it while the plugin loads, not later).
  image.fields, image.experts   ProtoFields / ProtoExperts by short name
                                (valid after image.proto()), e.g.
                                image.fields.bu_state, image.experts.relays_open.
  image.dissect(tvb, pinfo, tree, opts) -> info
      Adds an "EC-Link input image" / "EC-Link output image" subtree to tree.
      opts.kind    "input" or "output" (required)
      opts.offset  tvb offset of the first image byte present (default 0)
      opts.first   image offset of that byte (default 0)
      opts.length  number of image bytes present (default: the rest of tvb)
      opts.swap    true: every byte pair is swapped in tvb (Modbus registers:
                   image byte 2n in the low 8 bits); opts.first must be even
      opts.image_len  total image length: 64 input, 224 (default) or 20 output
      opts.label   text appended to the subtree title
      opts.generated  mark the subtree generated (an assembled image)
      opts.quiet   no expert info (an assembled copy of checked bytes)
      Fields fully covered by [first, first+length) are decoded with their
      checks; partly covered ones are named (eclink.cut), missing ones
      listed (eclink.not_covered). Returns info = { item = subtree,
      values = {name = number or ByteArray}, cut = {names},
      not_covered = {names}, findings = {...}, summary = "text" }.
  image.dissect_input(tvb, offset, pinfo, tree, opts)  /  image.dissect_output(...)
      The same with kind and offset given.
  image.check(kind, get, first, last) -> findings
      Pure value checks on image bytes first..last, get(i) -> byte value.
      Each finding: { field = name, expert = expert name, text = message,
      invalid = true when the value is outside the specification }.
  image.validate_input(bytes) -> ok, reason
      Pure: bytes is a ByteArray, a Lua string or a table indexed 0..63
      holding a full input image; ok when
      every value passes the checks and the EC-Link status is not "Unused"
      (the BU is talking EC-Link). Used by the Modbus heuristic.
  image.layout.input / image.layout.output   field descriptions
      { name, off, len, kind = "u8" | "u16" | "s16" | "bytes", label }.
  image.vs   value strings (bu_state, link, ru_state, ru_cable, ru_docked,
             ru_disabled, encoder_switch).
  Constants: INPUT_LEN 64, OUTPUT_CMD_LEN 20, OUTPUT_LEN 224,
             PERIODIC_BLOCK_LEN 200, PERIODIC_MAX 51200.
]]

local M = {}

M.INPUT_LEN = 64
M.OUTPUT_CMD_LEN = 20
M.OUTPUT_LEN = 224
M.PERIODIC_BLOCK_LEN = 200
M.PERIODIC_MAX = 51200

------------------------------------------------------------------------
-- Value tables (the same meanings as eglink)
------------------------------------------------------------------------
M.vs = {
    bu_state = {
        [0x00] = "Initial",
        [0x01] = "Stopped",
        [0x02] = "External link error",
        [0x03] = "Blocked",
        [0x04] = "Failed",
        [0x10] = "Disarmed",
        [0x11] = "Armed",
    },
    link = {
        [0] = "Unused",
        [1] = "Operational",
        [2] = "No link",
        [3] = "Link error",
        [4] = "Interface error",
        [5] = "Data error",
        [6] = "Passive",
    },
    ru_state = {
        [0] = "Initial",
        [1] = "Disarmed",
        [2] = "Armed",
        [3] = "Enabled",
        [4] = "Stopped",
    },
    ru_cable = { [0] = "Wireless", [1] = "Cable" },
    ru_docked = { [0] = "Not docked", [1] = "Docked" },
    ru_disabled = {
        [0] = "Enabled",
        [1] = "Disabled (tilting)",
        [2] = "Disabled (inactivity)",
        [3] = "Disabled (other causes)",
    },
    encoder_switch = { [0] = "Released", [1] = "Pushed" },
}

------------------------------------------------------------------------
-- Layouts
------------------------------------------------------------------------
local function entry(name, off, len, kind, label, vs)
    return { name = name, off = off, len = len, kind = kind, label = label, vs = vs }
end

local input = {
    entry("pci", 0, 1, "u8", "PCI (periodic counter input)"),
    entry("cci", 1, 1, "u8", "CCI (command counter input)"),
    entry("pai", 2, 1, "u8", "PAI (periodic acknowledge input)"),
    entry("cai", 3, 1, "u8", "CAI (command acknowledge input)"),
    entry("cmd_from_ru", 4, 16, "bytes", "Command from RU"),
    entry("bu_state", 20, 1, "u8", "BU state", "bu_state"),
    entry("vlaps", 21, 1, "u8", "VLAPs"),
    entry("unarmed_rus", 22, 1, "u8", "Unarmed RUs"),
    entry("eg_link_status", 23, 1, "u8", "EG-Link status", "link"),
    entry("ec_link_status", 24, 1, "u8", "EC-Link status", "link"),
    entry("c_link_status", 25, 1, "u8", "C-Link status", "link"),
    entry("armed_ru", 26, 2, "u16", "Armed RU"),
    entry("ru_state", 28, 1, "u8", "RU state", "ru_state"),
    entry("ru_battery", 29, 1, "u8", "RU battery"),
    entry("ru_rssi", 30, 1, "u8", "RU C-Link RSSI"),
    entry("ru_cable", 31, 1, "u8", "RU cable", "ru_cable"),
    entry("ru_docked", 32, 1, "u8", "RU docked", "ru_docked"),
    entry("ru_disabled", 33, 1, "u8", "RU disabled", "ru_disabled"),
}
for i = 1, 4 do
    input[#input + 1] = entry("joystick" .. i, 34 + 2 * (i - 1), 2, "s16", "Joystick " .. i)
end
for i = 1, 8 do
    input[#input + 1] = entry("switch" .. i, 42 + 2 * (i - 1), 2, "s16", "Switch " .. i)
end
input[#input + 1] = entry("encoder", 58, 1, "u8", "Encoder")
input[#input + 1] = entry("encoder_switch", 59, 1, "u8", "Encoder switch", "encoder_switch")
input[#input + 1] = entry("spare", 60, 4, "bytes", "Spare")

local output = {
    entry("pco", 0, 1, "u8", "PCO (periodic counter output)"),
    entry("cco", 1, 1, "u8", "CCO (command counter output)"),
    entry("pao", 2, 1, "u8", "PAO (periodic acknowledge output)"),
    entry("cao", 3, 1, "u8", "CAO (command acknowledge output)"),
    entry("cmd_to_ru", 4, 16, "bytes", "Command to RU"),
    entry("periodic_size", 20, 2, "u16", "Periodic data size"),
    entry("periodic_block", 22, 1, "u8", "Periodic data block"),
    entry("spare", 23, 1, "bytes", "Spare"),
    entry("periodic_data", 24, 200, "bytes", "Periodic data"),
}

M.layout = { input = input, output = output }

------------------------------------------------------------------------
-- Pure value checks
------------------------------------------------------------------------
local function covered(first, last, off, len)
    return off >= first and off + len - 1 <= last
end

local function u16(get, i) return get(i) * 256 + get(i + 1) end
local function s16(get, i)
    local v = u16(get, i)
    if v >= 0x8000 then v = v - 0x10000 end
    return v
end

local LINKS = { { "eg_link_status", 23, "EG-Link" }, { "ec_link_status", 24, "EC-Link" },
                { "c_link_status", 25, "C-Link" } }
local BOOLS = { { "ru_cable", 31, "RU cable" }, { "ru_docked", 32, "RU docked" } }
local ENCODER_SWITCH = { "encoder_switch", 59, "Encoder switch" }

local function check_input(get, first, last, out)
    local function add(field, expert, text, invalid)
        out[#out + 1] = { field = field, expert = expert, text = text, invalid = invalid }
    end
    local function has(off, len) return covered(first, last, off, len) end
    if has(20, 1) then
        local v = get(20)
        local name = M.vs.bu_state[v]
        if not name then
            add("bu_state", "bu_state_unknown", string.format("Unknown BU state 0x%02x", v), true)
        end
        if v < 0x10 then
            add("bu_state", "relays_open", string.format("ES-Link relays open: BU state %s (0x%02x)",
                name or "unknown", v))
        end
    end
    if has(21, 1) and get(21) > 3 then
        add("vlaps", "vlaps_range", string.format("VLAPs %d is out of range 0..3", get(21)), true)
    end
    for _, l in ipairs(LINKS) do
        if has(l[2], 1) and get(l[2]) > 6 then
            add(l[1], "link_range", string.format("%s status %d is undefined (0..6)", l[3], get(l[2])), true)
        end
    end
    if has(28, 1) then
        local v = get(28)
        if v > 4 then
            add("ru_state", "ru_state_range", string.format("RU state %d is undefined (0..4)", v), true)
        elseif v == 4 then
            add("ru_state", "ru_stopped", "RU stopped: ES-Link relays open")
        end
    end
    if has(29, 1) and get(29) > 100 then
        add("ru_battery", "percent_range", string.format("RU battery %d %% is over 100 %%", get(29)), true)
    end
    if has(30, 1) and get(30) > 100 then
        add("ru_rssi", "percent_range", string.format("RU C-Link RSSI %d %% is over 100 %%", get(30)), true)
    end
    local function check_bool(b)
        if has(b[2], 1) and get(b[2]) > 1 then
            add(b[1], "bool_range", string.format("%s %d is not 0 or 1", b[3], get(b[2])), true)
        end
    end
    for _, b in ipairs(BOOLS) do check_bool(b) end
    if has(33, 1) and get(33) > 3 then
        add("ru_disabled", "ru_disabled_range", string.format("RU disabled %d is undefined (0..3)", get(33)),
            true)
    end
    for j = 1, 4 do
        local off = 34 + 2 * (j - 1)
        if has(off, 2) then
            local v = s16(get, off)
            if v > 1000 or v < -1000 then
                add("joystick" .. j, "joystick_range",
                    string.format("Joystick %d position %d is out of range -1000..1000", j, v), true)
            end
        end
    end
    check_bool(ENCODER_SWITCH)
    if has(26, 2) and u16(get, 26) == 0 then
        for _, e in ipairs(input) do
            if e.off >= 28 and e.off < 60 and has(e.off, e.len) then
                local nz = false
                for i = e.off, e.off + e.len - 1 do
                    if get(i) ~= 0 then nz = true end
                end
                if nz then
                    add(e.name, "unarmed_not_zero",
                        string.format("Armed RU is 0 but %s is not 0", e.label), true)
                end
            end
        end
    end
    if has(60, 4) and (get(60) + get(61) + get(62) + get(63)) ~= 0 then
        add("spare", "spare_not_zero", "Spare bytes 60..63 are not 0", true)
    end
end

local function check_output(get, first, last, out)
    local function add(field, expert, text, invalid)
        out[#out + 1] = { field = field, expert = expert, text = text, invalid = invalid }
    end
    local function has(off, len) return covered(first, last, off, len) end
    if has(20, 2) then
        local size = u16(get, 20)
        if size > M.PERIODIC_MAX then
            add("periodic_size", "periodic_size_range",
                string.format("Periodic data size %d is over %d", size, M.PERIODIC_MAX), true)
        end
        if has(22, 1) then
            local block = get(22)
            local blocks = math.max(1, math.ceil(math.min(size, M.PERIODIC_MAX) / M.PERIODIC_BLOCK_LEN))
            if block >= blocks then
                add("periodic_block", "periodic_block_range",
                    string.format("Periodic data block %d is beyond the periodic data size %d (blocks 0..%d)",
                        block, size, blocks - 1), true)
            end
        end
    end
    if has(23, 1) and get(23) ~= 0 then
        add("spare", "spare_not_zero", string.format("Spare byte 23 is 0x%02x, not 0", get(23)), true)
    end
end

function M.check(kind, get, first, last)
    local out = {}
    first = first or 0
    if kind == "input" then
        check_input(get, first, last or (M.INPUT_LEN - 1), out)
    else
        check_output(get, first, last or (M.OUTPUT_LEN - 1), out)
    end
    return out
end

local function getter(bytes)
    local t = type(bytes)
    if t == "string" then
        return function(i) return bytes:byte(i + 1) end, #bytes
    elseif t == "table" then
        return function(i) return bytes[i] end, (bytes[0] ~= nil) and (#bytes + 1) or #bytes
    end
    return function(i) return bytes:get_index(i) end, bytes:len()
end

function M.validate_input(bytes)
    local get, n = getter(bytes)
    if n < M.INPUT_LEN then return false, "shorter than an input image" end
    for _, f in ipairs(M.check("input", get, 0, M.INPUT_LEN - 1)) do
        if f.invalid then return false, f.text end
    end
    if get(24) == 0 then return false, "EC-Link status is Unused" end
    return true
end

------------------------------------------------------------------------
-- Protocol, fields, experts (created once, on demand)
------------------------------------------------------------------------
local function make_fields()
    local f = {}
    f.image = ProtoField.string("eclink.image", "Image")
    for _, kind in ipairs({ "input", "output" }) do
        for _, e in ipairs(M.layout[kind]) do
            if not f[e.name] then
                local abbr = "eclink." .. e.name
                local vs = e.vs and M.vs[e.vs] or nil
                if e.kind == "u8" then
                    local b = (e.name == "bu_state") and base.HEX or base.DEC
                    f[e.name] = ProtoField.uint8(abbr, e.label, b, vs)
                elseif e.kind == "u16" then
                    f[e.name] = ProtoField.uint16(abbr, e.label, base.DEC)
                elseif e.kind == "s16" then
                    f[e.name] = ProtoField.int16(abbr, e.label, base.DEC)
                else
                    f[e.name] = ProtoField.bytes(abbr, e.label)
                end
            end
        end
    end
    f.es_relays_open = ProtoField.bool("eclink.es_relays_open", "ES-Link relays open")
    f.covered = ProtoField.string("eclink.covered", "Image bytes present")
    f.cut = ProtoField.string("eclink.cut", "Field cut by the access range")
    f.not_covered = ProtoField.string("eclink.not_covered", "Fields not covered")
    return f
end

local EXPERTS = {
    { "relays_open", "eclink.relays_open", "ES-Link relays open (BU state below 0x10)", "PROTOCOL", "WARN" },
    { "ru_stopped", "eclink.ru_stopped", "RU stopped: ES-Link relays open", "PROTOCOL", "WARN" },
    { "bu_state_unknown", "eclink.bu_state.unknown", "Unknown BU state", "PROTOCOL", "ERROR" },
    { "vlaps_range", "eclink.vlaps.range", "VLAPs out of range 0..3", "PROTOCOL", "ERROR" },
    { "link_range", "eclink.link_status.range", "Link status undefined (0..6)", "PROTOCOL", "ERROR" },
    { "ru_state_range", "eclink.ru_state.range", "RU state undefined (0..4)", "PROTOCOL", "ERROR" },
    { "percent_range", "eclink.percent.range", "Percentage over 100", "PROTOCOL", "ERROR" },
    { "bool_range", "eclink.bool.range", "Flag is not 0 or 1", "PROTOCOL", "ERROR" },
    { "ru_disabled_range", "eclink.ru_disabled.range", "RU disabled undefined (0..3)", "PROTOCOL", "ERROR" },
    { "joystick_range", "eclink.joystick.range", "Joystick out of range -1000..1000", "PROTOCOL", "ERROR" },
    { "unarmed_not_zero", "eclink.unarmed_not_zero", "Armed RU is 0 but a later field is not 0",
      "PROTOCOL", "ERROR" },
    { "spare_not_zero", "eclink.spare.not_zero", "Spare not 0", "PROTOCOL", "WARN" },
    { "periodic_size_range", "eclink.periodic_size.range", "Periodic data size over 51200",
      "PROTOCOL", "ERROR" },
    { "periodic_block_range", "eclink.periodic_block.range", "Periodic data block beyond the size",
      "PROTOCOL", "ERROR" },
    { "partial", "eclink.partial", "Access covers part of the image", "SEQUENCE", "CHAT" },
    { "bad_length", "eclink.bad_length", "Not an EC-Link image length", "MALFORMED", "ERROR" },
}

local GROUPS = { PROTOCOL = PI_PROTOCOL, SEQUENCE = PI_SEQUENCE, MALFORMED = PI_MALFORMED }
local SEVERITIES = { WARN = PI_WARN, ERROR = PI_ERROR, CHAT = PI_CHAT, NOTE = PI_NOTE }

local dissect_raw -- forward

function M.proto()
    if M._proto then return M._proto end
    local p = Proto("eclink", "VisionRemote EC-Link")
    M.fields = make_fields()
    M.experts = {}
    local flist, elist = {}, {}
    for _, pf in pairs(M.fields) do flist[#flist + 1] = pf end
    for _, e in ipairs(EXPERTS) do
        local ex = ProtoExpert.new(e[2], e[3], GROUPS[e[4]], SEVERITIES[e[5]])
        M.experts[e[1]] = ex
        elist[#elist + 1] = ex
    end
    p.fields = flist
    p.experts = elist
    p.dissector = dissect_raw
    M._proto = p
    return p
end

------------------------------------------------------------------------
-- Dissection
------------------------------------------------------------------------
function M.dissect(tvb, pinfo, tree, opts)
    local _ = pinfo
    local kind = opts.kind
    local offset = opts.offset or 0
    local first = opts.first or 0
    local image_len = opts.image_len or (kind == "input" and M.INPUT_LEN or M.OUTPUT_LEN)
    local length = opts.length or (tvb:len() - offset)
    if first + length > image_len then length = image_len - first end
    local last = first + length - 1
    local swap = opts.swap and true or false

    -- tvb offset of image byte i
    local function pos(i)
        local rel = i - first
        if swap then
            if rel % 2 == 0 then rel = rel + 1 else rel = rel - 1 end
        end
        return offset + rel
    end
    -- the image bytes first..last as one string in image order (read once;
    -- an odd swapped length falls back to reading byte by byte)
    local img
    if length > 0 and tvb:len() - offset >= length and not (swap and length % 2 == 1) then
        img = tvb:raw(offset, length)
        if swap then img = img:gsub("(.)(.)", "%2%1") end
    end
    local function get(i)
        if img then return img:byte(i - first + 1) end
        return tvb(pos(i), 1):uint()
    end
    local function raw(off, len)
        if img then return ByteArray.new(img:sub(off - first + 1, off - first + len), true) end
        local ba = ByteArray.new()
        ba:set_size(len)
        for i = 0, len - 1 do ba:set_index(i, get(off + i)) end
        return ba
    end

    local title = (kind == "input") and "EC-Link input image" or "EC-Link output image"
    if length < image_len then
        title = title .. string.format(", bytes %d-%d of %d", first, last, image_len)
    end
    if opts.label then title = title .. " " .. opts.label end
    local p = M.proto()
    local f = M.fields
    local span = (length > 0) and tvb(offset, length) or tvb(offset, 0)
    local item = tree:add(p, span, title)
    if opts.generated then item:set_generated() end
    local it = item:add(f.image, span, kind)
    it:set_generated()
    local info = { item = item, values = {}, cut = {}, not_covered = {}, items = {} }
    if length < image_len then
        item:add(f.covered, span, string.format("%d-%d of %d", first, last, image_len)):set_generated()
    end

    for _, e in ipairs(M.layout[kind]) do
        local e_last = e.off + e.len - 1
        if e.off >= image_len then
            break
        elseif e.off >= first and e_last <= last then
            local ti
            if e.kind == "bytes" then
                local v = raw(e.off, e.len)
                info.values[e.name] = v
                -- swapped pairs: a multi-byte blob starts and ends on a pair boundary
                local lo = (e.len == 1) and pos(e.off) or (offset + e.off - first)
                if swap then
                    ti = item:add(f[e.name], tvb(lo, e.len), v:raw())
                else
                    ti = item:add(f[e.name], tvb(lo, e.len))
                end
            elseif e.kind == "u8" then
                ti = item:add(f[e.name], tvb(pos(e.off), 1))
                info.values[e.name] = get(e.off)
            else
                local v = (e.kind == "s16") and s16(get, e.off) or u16(get, e.off)
                info.values[e.name] = v
                if swap then
                    ti = item:add_le(f[e.name], tvb(pos(e.off + 1), 2))
                else
                    ti = item:add(f[e.name], tvb(pos(e.off), 2))
                end
            end
            if e.name == "ru_battery" or e.name == "ru_rssi" then ti:append_text(" %") end
            info.items[e.name] = ti
        elseif e_last >= first and e.off <= last then
            local text = string.format("%s (image bytes %d-%d; %d-%d present)", e.name, e.off, e_last,
                math.max(e.off, first), math.min(e_last, last))
            info.cut[#info.cut + 1] = e.name
            item:add(f.cut, span, text):set_generated()
        else
            info.not_covered[#info.not_covered + 1] = e.name
        end
    end
    if #info.not_covered > 0 then
        item:add(f.not_covered, span, table.concat(info.not_covered, ", ")):set_generated()
    end
    if length < image_len and not opts.quiet then
        item:add_proto_expert_info(M.experts.partial,
            string.format("Image bytes %d-%d of %d present%s", first, last, image_len,
                (#info.cut > 0) and ("; cut: " .. table.concat(info.cut, ", ")) or ""))
    end

    info.findings = M.check(kind, get, first, last)
    for _, fd in ipairs(opts.quiet and {} or info.findings) do
        local target = info.items[fd.field] or item
        if fd.expert == "relays_open" then
            local g = item:add(f.es_relays_open, tvb(pos(20), 1), true)
            g:set_generated()
        end
        target:add_proto_expert_info(M.experts[fd.expert], fd.text)
    end

    -- one-line summary
    local parts = {}
    local v = info.values
    if kind == "input" then
        if v.pci then parts[#parts + 1] = "PCI=" .. v.pci end
        if v.cci then parts[#parts + 1] = "CCI=" .. v.cci end
        if v.bu_state then parts[#parts + 1] = "BU " .. (M.vs.bu_state[v.bu_state] or "?") end
        if v.ru_state then parts[#parts + 1] = "RU " .. (M.vs.ru_state[v.ru_state] or "?") end
    else
        if v.pco then parts[#parts + 1] = "PCO=" .. v.pco end
        if v.cco then parts[#parts + 1] = "CCO=" .. v.cco end
        if v.cao then parts[#parts + 1] = "CAO=" .. v.cao end
        if v.periodic_size then parts[#parts + 1] = "size=" .. v.periodic_size end
        if v.periodic_block then parts[#parts + 1] = "block=" .. v.periodic_block end
    end
    if #parts > 0 then item:append_text(": " .. table.concat(parts, " ")) end
    if length < image_len then parts[#parts + 1] = string.format("bytes %d-%d", first, last) end
    info.summary = table.concat(parts, " ")
    return info
end

function M.dissect_input(tvb, offset, pinfo, tree, opts)
    local o = {}
    for k, val in pairs(opts or {}) do o[k] = val end
    o.kind, o.offset = "input", offset
    return M.dissect(tvb, pinfo, tree, o)
end

function M.dissect_output(tvb, offset, pinfo, tree, opts)
    local o = {}
    for k, val in pairs(opts or {}) do o[k] = val end
    o.kind, o.offset = "output", offset
    return M.dissect(tvb, pinfo, tree, o)
end

-- The "eclink" dissector: a raw image, 64 bytes input, 20 or 224 bytes output.
dissect_raw = function(tvb, pinfo, tree)
    local n = tvb:len()
    pinfo.cols.protocol = "EC-Link"
    local info
    if n == M.INPUT_LEN then
        info = M.dissect(tvb, pinfo, tree, { kind = "input", image_len = M.INPUT_LEN })
        pinfo.cols.info = "Input image " .. info.summary
    elseif n == M.OUTPUT_LEN or n == M.OUTPUT_CMD_LEN then
        info = M.dissect(tvb, pinfo, tree, { kind = "output", image_len = n })
        pinfo.cols.info = "Output image " .. info.summary
    else
        local item = tree:add(M.proto(), tvb(), "EC-Link image")
        item:add_proto_expert_info(M.experts.bad_length,
            string.format("%d bytes is not an EC-Link image (input 64, output 20 or 224)", n))
        pinfo.cols.info = string.format("Not an EC-Link image (%d bytes)", n)
    end
    return n
end

return M
