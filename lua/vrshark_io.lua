--[[ vrshark_io.lua -- the machine's own data, named from its IO list.

The areas whose layout is machine-specific (the terminal data of MC-MB2-PN,
SP-14-023 §3.1.3/§3.2.3; the RU application content of EG-Link and EC-Link,
TS-0006 §1 and TS-0007 §1.1) are decoded from CSV machine descriptions in
the folder VRSHARK_IO_DIR or <personal configuration>/vrshark-io
(docs/io.md). The loading and the decoder live in vrshark/iodata.luam, the
CSV rules in vrshark/iodesc.luam; this plugin hooks the EG-Link areas:

  eglink.data table key   area             device key
  vrci                    cmd.from_ru      origin (the BU's, eglink.origin)
  vrco                    cmd.to_ru        origin (the BU's, as learned by the analysis)
  vrpo                    periodic.to_ru   origin (the BU's, as learned by the analysis)

  The data handed on is the 16 bytes of command data (VRCI/VRCO) or the
  periodic data of a burst (VRPO; reassembled when split).

The MC-MB2-PN and EC-Link plugins call iodata.decode() themselves.
]]

local dir = debug.getinfo(1, "S").source:match("^@(.*)[/\\]")
package.path = dir .. "/?.luam;" .. package.path
set_plugin_info(require("vrshark.version").info("Machine data decoded from the machine's IO list (CSV)"))
local iodata = require("vrshark.iodata")

-- The BU origin: the packet's own for BU packets; controller packets carry
-- origin 0, so theirs is the BU origin the EG-Link analysis learned. The C
-- plugin hands both over in pinfo.match_uint (the packet's origin in the low
-- 16 bits, the analysis' BU origin in the high 16, 0: not known), not as
-- Lua Fields: once any Lua Field exists, Wireshark builds the frame tree of
-- every frame of every protocol to feed it. Without the EG-Link C plugin the
-- Lua EG-Link (eglink.lua, loaded before this file) owns the table and hands
-- the same number over in vrshark/eglink_data.luam's match; without either
-- there is no table: the EG-Link hook is then left out.
local eglink_data = require("vrshark.eglink_data")
local have_eglink, eglink_table = pcall(DissectorTable.get, require("vrshark.seam").EGLINK_DATA_TABLE)
have_eglink = have_eglink and eglink_table ~= nil
-- The controller's packets are matched to their BU's origin by the group
-- (or address) and input port, as the EG-Link analysis does: learned from
-- the BU's VRCI, kept per frame once known.
local bu_origin_of = {}   -- "dst address:input port" -> origin
local frame_origin = {}   -- frame number -> origin

local function origin(pinfo, from_bu)
    local known = frame_origin[pinfo.number]
    if known then return known end
    local handed = eglink_data.match or pinfo.match_uint or 0
    local value = handed % 65536
    if from_bu then
        if value ~= 0 then
            bu_origin_of[tostring(pinfo.dst) .. ":" .. pinfo.dst_port] = value
        end
    elseif value == 0 then
        local b = math.floor(handed / 65536)
        value = (b ~= 0 and b) or bu_origin_of[tostring(pinfo.dst) .. ":" .. (pinfo.dst_port - 2)]
    end
    if value == 0 then value = nil end
    frame_origin[pinfo.number] = value
    return value
end

local AREAS = {
    vrci = { area = "cmd.from_ru", from_bu = true },
    vrco = { area = "cmd.to_ru" },
    vrpo = { area = "periodic.to_ru" },
}

local hooked = {}  -- key -> true while the dissector is in the table

-- Hooked only for an area described: each call of a Lua dissector costs the
-- EG-Link plugin a microsecond or two, on more than half of its packets.
-- The lists are read again when a capture is opened (iodata.refresh), so
-- the hooks follow the areas described then.
local function hook_described()
    if not have_eglink then return end
    for key, a in pairs(AREAS) do
        local want = iodata.areas[a.area] ~= nil
        if want and not hooked[key] then
            eglink_table:add(key, a.proto)
        elseif hooked[key] and not want then
            eglink_table:remove(key, a.proto)
        end
        hooked[key] = want or nil
    end
end

for key, a in pairs(AREAS) do
    local d = Proto("vrshark_io_eglink_" .. key, "Machine data from EG-Link " .. key:upper())
    function d.dissector(tvb, pinfo, tree)
        -- Nothing described for the area: decline, so that the decode
        -- (protocol stack included) is exactly as without this plugin.
        if not iodata.areas[a.area] then return 0 end
        local o = origin(pinfo, a.from_bu)
        iodata.decode(a.area, o and { origin = o } or nil, tvb(), tree, pinfo)
        return tvb:len()
    end
    a.proto = d
end
hook_described()
iodata.on_change(hook_described)

iodata.on_init(function()
    bu_origin_of = {}
    frame_origin = {}
end)
