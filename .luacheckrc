-- luacheck configuration for the Wireshark Lua plugins under lua/.
std = "lua52"
max_line_length = 120
-- The Wireshark Lua API (globals the plugins read; they define none).
read_globals = {
    "Proto", "ProtoField", "ProtoExpert", "Field", "FieldInfo", "DissectorTable", "Dissector",
    "Pref", "PI_MALFORMED", "PI_PROTOCOL", "PI_SEQUENCE", "PI_SECURITY", "PI_RESPONSE_CODE",
    "PI_REQUEST_CODE", "PI_UNDECODED", "PI_REASSEMBLE", "PI_DEBUG", "PI_COMMENTS_GROUP",
    "PI_CHAT", "PI_NOTE", "PI_WARN", "PI_ERROR", "PI_COMMENT",
    "ByteArray", "Tvb", "TvbRange", "UInt64", "Int64", "Address", "NSTime", "Pinfo", "TreeItem", "Column",
    "base", "ftypes", "frametype", "bit", "wtap", "wtap_encaps", "expert", "register_postdissector",
    "set_plugin_info", "get_version", "register_stat_cmd_arg", "Listener", "GUI_ENABLED",
    "register_menu", "MENU_TOOLS_UNSORTED", "MENU_STAT_UNSORTED", "TextWindow", "retap_packets",
    "DESEGMENT_ONE_MORE_SEGMENT", "persconffile_path", "datafile_path", "all_field_infos",
    "dissect_tcp_pdus", "Dir", "report_failure", "gui_enabled", "critical", "warn", "message", "info", "debug",
}
-- Lua 5.4 (Wireshark 4.4 and later) has no bit32: use the bit library.
not_globals = { "bit32" }
