-- vrshark.wrap: calling the built-in dissector that a plugin wraps
-- (mbtcp for EC-Link over Modbus/TCP, PN-RT for PROFINET cyclic data).
--
-- Dissector.call() catches the exception of a malformed packet inside the
-- called dissector, shows it in the tree ("[Malformed Packet: ...]", with its
-- expert info) and then raises a Lua error, which would add a misleading
-- "Lua Error" on top. The wrapped dissector's own report is what the user
-- needs, so call() absorbs that error and tells the caller to stop.
--
-- No side effects at load time: Wireshark runs this file as a plugin too.
local M = {}

-- Returns the wrapped dissector's result, or nil when it reported the
-- packet as malformed (the report is already in the tree).
function M.call(dissector, tvb, pinfo, tree)
    local ok, consumed = pcall(dissector.call, dissector, tvb, pinfo, tree)
    if ok then return consumed end
    return nil
end

return M
