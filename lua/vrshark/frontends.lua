-- vrshark.frontends: the transport front ends of the C plugin (eglink.so,
-- plugins/eglink/vrshark-frontends.c), when it is loaded.
--
-- With them, Wireshark's own dissectors (PN-RT, DCE/RPC, mbtcp) run first in
-- C, and a Lua decoder is called only for the FrameIDs and TCP connections
-- it registered or still considers: foreign traffic never enters Lua.
-- Without them (a Wireshark without the C plugin) the Lua plugins wrap
-- those dissectors themselves, as before.
--
--   pn_frame_id  DissectorTable "vrshark.pn.frame_id": FrameID -> decoder
--   pn_hook      DissectorTable "vrshark.pn.hook": "candidate", "pending",
--                "connect" -> decoder
--   mb_hook      DissectorTable "vrshark.mbtcp.hook": "heuristic", "always"
--                -> decoder
--   mb_front     Dissector "vrshark.mbtcp": mbtcp, then mb_hook; the
--                decoder's TCP port gets it instead of mbtcp
--
-- All nil when the C plugin is absent. The C plugin registers before the Lua
-- plugins load, so the tables exist when this module is first required.
-- No side effects at load time: Wireshark runs this file as a plugin too.
local M = {}

local function get(kind, name)
    local ok, v = pcall(kind.get, name)
    if ok then return v end
    return nil
end

M.pn_frame_id = get(DissectorTable, "vrshark.pn.frame_id")
M.pn_hook = get(DissectorTable, "vrshark.pn.hook")
M.mb_hook = get(DissectorTable, "vrshark.mbtcp.hook")
M.mb_front = M.mb_hook and get(Dissector, "vrshark.mbtcp")

-- Registers `proto` under `key` in `tbl` when `on`, removes it otherwise.
function M.hook(tbl, key, proto, on)
    if on then tbl:add(key, proto) else tbl:remove(key, proto) end
end

return M
