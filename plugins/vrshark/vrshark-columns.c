/* vrshark-columns.c
 * Column text of the Lua decoders, written in C while a front end calls
 * them.
 *
 * A Lua decoder that writes the Protocol and Info columns through
 * pinfo.cols makes a Columns object, and for an append a Column object too:
 * Lua userdata with finalizers, which the collector has to run. In the
 * packet list and with tshark -Y every frame writes its Info text, and on
 * EC-Link over Modbus/TCP those objects and the joined text cost a
 * decoder as much time again as all its other work over the floor
 * (docs/quality.md). These functions take the text as parts, join them
 * here and write them with col_add_str() / col_append_str(), as
 * pinfo.cols does: no object is made, and the parts are strings the
 * decoder keeps (nothing new for the collector).
 *
 * lua/vrshark/frontends.luam takes them with package.loadlib() from this
 * plugin's own file (VRSHARK_FRONTENDS_LIB): the same loaded copy, so they
 * see the frame the front end is calling the decoder for. Outside such a
 * call they write nothing and return false, and the decoder writes through
 * pinfo.cols as it does without the C plugin.
 *
 *   vrshark_lua_set_cols(protocol, part, ...)  Protocol := protocol,
 *                                              Info := the parts joined
 *   vrshark_lua_append_info(part, ...)         Info .. the parts joined
 *
 * Only three functions of the Lua C API are used, the same in Lua 5.1 to
 * 5.4. They are weak references resolved in the process that loaded
 * Wireshark's Lua, so the plugin neither links nor needs the Lua headers.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#define _GNU_SOURCE /* dladdr */
#include "eglink-compat.h"

#include <dlfcn.h>
#include <string.h>

#include <epan/packet.h>
#include <epan/column-utils.h>

#include "vrshark-columns.h"
#include "vrshark-frontends.h"

typedef struct lua_State lua_State;

extern int lua_gettop(lua_State *L) __attribute__((weak));
extern const char *lua_tolstring(lua_State *L, int idx, size_t *len) __attribute__((weak));
extern void lua_pushboolean(lua_State *L, int b) __attribute__((weak));

#define VRSHARK_EXPORT __attribute__((visibility("default")))

static packet_info *cols_pinfo;

packet_info *
vrshark_columns_enter(packet_info *pinfo)
{
    packet_info *outer = cols_pinfo;

    cols_pinfo = pinfo;
    return outer;
}

void
vrshark_columns_leave(packet_info *outer)
{
    cols_pinfo = outer;
}

/* The parts from argument `first` on (as many as the call has: an EC-Link
 * image summary alone is a dozen), joined into buf (cut at its size, as
 * the column is); FALSE when one is not a string. */
static gboolean
join_parts(lua_State *L, int first, char *buf, size_t size)
{
    int n = lua_gettop(L), i;
    size_t used = 0;

    for (i = first; i <= n; i++) {
        size_t len;
        const char *s = lua_tolstring(L, i, &len);

        if (!s)
            return FALSE;
        if (len > size - 1 - used)
            len = size - 1 - used;
        memcpy(buf + used, s, len);
        used += len;
    }
    buf[used] = '\0';
    return TRUE;
}

/* (exported: package.loadlib finds them by name) */
VRSHARK_EXPORT int vrshark_lua_set_cols(lua_State *L);
VRSHARK_EXPORT int vrshark_lua_append_info(lua_State *L);

int
vrshark_lua_set_cols(lua_State *L)
{
    char buf[COL_MAX_INFO_LEN];
    const char *protocol;

    if (!cols_pinfo || lua_gettop(L) < 1 || !(protocol = lua_tolstring(L, 1, NULL)) ||
        !join_parts(L, 2, buf, sizeof buf)) {
        lua_pushboolean(L, 0);
        return 1;
    }
    if (cols_pinfo->cinfo) {
        col_add_str(cols_pinfo->cinfo, COL_PROTOCOL, protocol);
        col_add_str(cols_pinfo->cinfo, COL_INFO, buf);
    }
    lua_pushboolean(L, 1);
    return 1;
}

int
vrshark_lua_append_info(lua_State *L)
{
    char buf[COL_MAX_INFO_LEN];

    if (!cols_pinfo || !join_parts(L, 1, buf, sizeof buf)) {
        lua_pushboolean(L, 0);
        return 1;
    }
    if (cols_pinfo->cinfo)
        col_append_str(cols_pinfo->cinfo, COL_INFO, buf);
    lua_pushboolean(L, 1);
    return 1;
}

void
vrshark_columns_register(void)
{
    Dl_info info;

    /* (the Lua C API is there only in a Wireshark with Lua) */
    if (!lua_gettop || !lua_tolstring || !lua_pushboolean)
        return;
    if (dladdr((void *)vrshark_lua_set_cols, &info) && info.dli_fname && info.dli_fname[0] == '/')
        g_setenv(VRSHARK_ENV_FRONTENDS_LIB, info.dli_fname, TRUE);
}
