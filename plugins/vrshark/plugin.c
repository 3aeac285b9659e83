/* plugin.c
 * Plugin entry points of the vrshark C plugin (vrshark.so: the EG-Link
 * dissector and the front ends of the Lua decoders), as Wireshark's
 * generated plugin.c would write them. What differs between Wireshark 4.0 and 4.6
 * (plugin_describe() from 4.2 on) is decided in eglink-compat.h.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#define WS_BUILD_DLL
#include "eglink-compat.h"

#include <epan/proto.h>

#ifndef VERSION
#define VERSION "0.1.0"
#endif

WS_DLL_PUBLIC_DEF const char plugin_version[] = VERSION;
WS_DLL_PUBLIC_DEF const int plugin_want_major = WIRESHARK_VERSION_MAJOR;
WS_DLL_PUBLIC_DEF const int plugin_want_minor = WIRESHARK_VERSION_MINOR;

WS_DLL_PUBLIC void plugin_register(void);
#ifdef EGLINK_HAVE_PLUGIN_DESCRIBE
WS_DLL_PUBLIC uint32_t plugin_describe(void);
#endif

#include "vrshark-frontends.h"

void proto_register_eglink(void);
void proto_reg_handoff_eglink(void);

void plugin_register(void)
{
    static proto_plugin plug_eglink;

    plug_eglink.register_protoinfo = proto_register_eglink;
    plug_eglink.register_handoff = proto_reg_handoff_eglink;
    proto_register_plugin(&plug_eglink);

    /* The transport front ends of the Lua dissectors (vrshark-frontends.c) */
    static proto_plugin plug_frontends;

    plug_frontends.register_protoinfo = proto_register_vrshark_frontends;
    plug_frontends.register_handoff = proto_reg_handoff_vrshark_frontends;
    proto_register_plugin(&plug_frontends);
}

#ifdef EGLINK_HAVE_PLUGIN_DESCRIBE
uint32_t plugin_describe(void)
{
    return WS_PLUGIN_DESC_DISSECTOR;
}
#endif
