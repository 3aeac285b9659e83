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
 * and the two through which the Lua side's clock (lua/vrshark/deadlines.luam)
 * tells the front ends when to call it for a frame that otherwise does not
 * reach Lua (vrshark_clock_wanted(), hook VRSHARK_PN_HOOK_CLOCK):
 *
 *   vrshark_lua_clock_due(t)        the earliest deadline, absolute seconds
 *                                   as text ("%.17g": the same double as
 *                                   Lua's; "inf": none)
 *   vrshark_lua_clock_mark(number)  frame `number` carries a finding: later
 *                                   passes call the clock on it
 *
 * These write outside a decoder call too (a file's first deadline is armed
 * by a decoder; a mark is kept for the passes after).
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

double vrshark_clock_due = 1.0 / 0.0;
GHashTable *vrshark_clock_marks;

packet_info *
vrshark_columns_enter(packet_info *pinfo)
{
    packet_info *outer = cols_pinfo;

    cols_pinfo = pinfo;
    return outer;
}

packet_info *
vrshark_columns_pinfo(void)
{
    return cols_pinfo;
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

VRSHARK_EXPORT int vrshark_lua_clock_due(lua_State *L);
VRSHARK_EXPORT int vrshark_lua_clock_mark(lua_State *L);

int
vrshark_lua_clock_due(lua_State *L)
{
    const char *text = lua_gettop(L) >= 1 ? lua_tolstring(L, 1, NULL) : NULL;
    char *end;
    double t;

    if (!text) {
        lua_pushboolean(L, 0);
        return 1;
    }
    t = g_ascii_strtod(text, &end);
    /* (nothing read: no deadline, rather than one at 0 that calls Lua on
     * every frame) */
    vrshark_clock_due = end == text ? 1.0 / 0.0 : t;
    lua_pushboolean(L, 1);
    return 1;
}

int
vrshark_lua_clock_mark(lua_State *L)
{
    const char *text = lua_gettop(L) >= 1 ? lua_tolstring(L, 1, NULL) : NULL;
    guint64 number;

    if (!text || (number = g_ascii_strtoull(text, NULL, 10)) == 0 || number > G_MAXUINT32) {
        lua_pushboolean(L, 0);
        return 1;
    }
    if (!vrshark_clock_marks)
        vrshark_clock_marks = g_hash_table_new(g_direct_hash, g_direct_equal);
    g_hash_table_add(vrshark_clock_marks, GUINT_TO_POINTER((guint)number));
    lua_pushboolean(L, 1);
    return 1;
}

void
vrshark_clock_reset(void)
{
    vrshark_clock_due = 1.0 / 0.0;
    if (vrshark_clock_marks)
        g_hash_table_remove_all(vrshark_clock_marks);
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
