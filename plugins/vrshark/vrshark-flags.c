/* vrshark-flags.c
 * The Lua side's state that the front ends read on every frame
 * (vrshark-frontends.c), kept here as plain variables and set by the Lua
 * side the moment it changes: no dissector-table entry stands for a
 * boolean, and nothing is cached on a rule about when the Lua side may
 * change what.
 *
 * lua/vrshark/frontends.luam takes these with package.loadlib() from this
 * plugin's own file, as it takes the column writers (vrshark-columns.c),
 * and sets every one as soon as it has them:
 *
 *   vrshark_lua_flag(name, on)       flag VRSHARK_FLAG_PN_PENDING or
 *                                    VRSHARK_FLAG_PN_RESPONSE on or off;
 *                                    false back for any other name
 *   vrshark_lua_servers(name, ...)   the listed servers, all of them
 *                                    (VRSHARK_MB_SERVER_PREFIX "ADDR:PORT"
 *                                    or "ADDR"; none: no server listed);
 *                                    false back for another name
 *   vrshark_lua_mb_hooks_changed()   the Lua side added or removed an entry
 *                                    of VRSHARK_MB_HOOK_TABLE
 *
 * Where the Lua side cannot take them (no package.loadlib), the state stays
 * as it starts, which decodes the same, only slower: both flags on (the
 * front ends hand over every candidate and Connect response the Lua side
 * might want, and it refuses what it does not), no list (the front end
 * looks the listed servers up as entries of VRSHARK_MB_HOOK_TABLE, which
 * the Lua side then writes), the Modbus hooks read on every frame.
 *
 * Nothing here is reset when a file starts: the Lua side sets its state
 * anew then (its init routines), and the order of the two sides' init
 * routines is not known.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-compat.h"

#include <string.h>

#include "vrshark-flags.h"
#include "vrshark-frontends.h"

typedef struct lua_State lua_State;

/* (weak, resolved in the process that loaded Wireshark's Lua: see
 * vrshark-columns.c) */
extern int lua_gettop(lua_State *L) __attribute__((weak));
extern const char *lua_tolstring(lua_State *L, int idx, size_t *len) __attribute__((weak));
extern int lua_toboolean(lua_State *L, int idx) __attribute__((weak));
extern void lua_pushboolean(lua_State *L, int b) __attribute__((weak));

#define VRSHARK_EXPORT __attribute__((visibility("default")))

gboolean vrshark_flag_pn_pending = TRUE;
gboolean vrshark_flag_pn_response = TRUE;
GHashTable *vrshark_mb_servers;
guint vrshark_mb_hooks_changes;

VRSHARK_EXPORT int vrshark_lua_flag(lua_State *L);
VRSHARK_EXPORT int vrshark_lua_servers(lua_State *L);
VRSHARK_EXPORT int vrshark_lua_mb_hooks_changed(lua_State *L);

int
vrshark_lua_flag(lua_State *L)
{
    const char *name = lua_gettop(L) >= 2 ? lua_tolstring(L, 1, NULL) : NULL;
    gboolean *flag = NULL;

    if (name && strcmp(name, VRSHARK_FLAG_PN_PENDING) == 0)
        flag = &vrshark_flag_pn_pending;
    else if (name && strcmp(name, VRSHARK_FLAG_PN_RESPONSE) == 0)
        flag = &vrshark_flag_pn_response;
    if (flag)
        *flag = lua_toboolean(L, 2) != 0;
    lua_pushboolean(L, flag != NULL);
    return 1;
}

int
vrshark_lua_servers(lua_State *L)
{
    int n = lua_gettop(L), i;
    size_t prefix = strlen(VRSHARK_MB_SERVER_PREFIX);

    /* (all names checked first: a list with a wrong one changes nothing) */
    for (i = 1; i <= n; i++) {
        const char *name = lua_tolstring(L, i, NULL);

        if (!name || strncmp(name, VRSHARK_MB_SERVER_PREFIX, prefix) != 0) {
            lua_pushboolean(L, 0);
            return 1;
        }
    }
    if (!vrshark_mb_servers)
        vrshark_mb_servers = g_hash_table_new_full(g_str_hash, g_str_equal, g_free, NULL);
    g_hash_table_remove_all(vrshark_mb_servers);
    for (i = 1; i <= n; i++)
        g_hash_table_add(vrshark_mb_servers, g_strdup(lua_tolstring(L, i, NULL)));
    lua_pushboolean(L, 1);
    return 1;
}

int
vrshark_lua_mb_hooks_changed(lua_State *L)
{
    /* (never 0 again: 0 is "never said") */
    if (++vrshark_mb_hooks_changes == 0)
        vrshark_mb_hooks_changes = 1;
    lua_pushboolean(L, 1);
    return 1;
}
