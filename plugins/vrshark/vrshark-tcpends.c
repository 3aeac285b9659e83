/* vrshark-tcpends.c
 * The TCP segments that end a BU's connection (FIN, RST), for the Lua
 * decoder of EC-Link over Modbus/TCP (lua/eclink_modbus.lua), with the C
 * plugin.
 *
 * Such a segment carries no payload, and TCP hands none of those to a
 * subdissector: only a listener of the "tcp" tap sees it. A Lua listener
 * costs a Lua call and a table of the TCP header on every TCP frame, a
 * sixth of what a BU's Modbus/TCP costs with -Y (docs/quality.md). This
 * listener, in C, keeps the segments with FIN or RST of the connections
 * the decoder named; the front ends hand them to the decoder (hook
 * VRSHARK_MB_HOOK_TCP_END, vrshark-frontends.c) before their own work on
 * the next frame they see, where the Lua listener would have armed the
 * finding for that frame's tick.
 *
 * lua/vrshark/frontends.luam takes these with package.loadlib() from this
 * plugin's own file, as the column writers (vrshark-columns.c):
 *
 *   vrshark_lua_tcp_end_watch(key, client_port)
 *       while a front end calls the decoder for a frame of a connection:
 *       that connection (its addresses and ports, both directions) is
 *       named `key`, its client the end on client_port; the listener is
 *       registered on the first call (and stays for the process, as a Lua
 *       one would). false back outside a front end's call (the decoder
 *       then listens itself).
 *   vrshark_lua_tcp_ends()
 *       the segments kept since the last call, then forgotten: one line
 *       each, "KEY\tNUMBER\tFLAGS\tTIME\tFROM_CLIENT\n" (TIME: the frame's
 *       absolute time in seconds, "%.17g"; FROM_CLIENT 1 or 0); "" for none.
 *
 * The listener runs when the taps run: on every pass in Wireshark, in the
 * second pass only with tshark -2, as a Lua listener does. The connections
 * and the segments kept are the file's (vrshark_tcp_ends_reset()).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-compat.h"

#include <string.h>

#include <epan/packet.h>
#include <epan/tap.h>
#include <epan/address.h>
#include <epan/dissectors/packet-tcp.h>

#include "vrshark-columns.h"
#include "vrshark-tcpends.h"

typedef struct lua_State lua_State;

/* (weak, resolved in the process that loaded Wireshark's Lua: see
 * vrshark-columns.c) */
extern int lua_gettop(lua_State *L) __attribute__((weak));
extern const char *lua_tolstring(lua_State *L, int idx, size_t *len) __attribute__((weak));
extern void lua_pushboolean(lua_State *L, int b) __attribute__((weak));
extern const char *lua_pushlstring(lua_State *L, const char *s, size_t len) __attribute__((weak));

#define VRSHARK_EXPORT __attribute__((visibility("default")))

#define TCP_FIN 0x01
#define TCP_RST 0x04

gboolean vrshark_tcp_ends_pending;

/* One direction of a named connection: sender, receiver and their ports. */
typedef struct {
    address src, dst;
    guint32 src_port, dst_port;
} tcp_dir_t;

typedef struct {
    const char *key;        /* the decoder's name of the connection */
    gboolean from_client;   /* this direction is the client's */
} tcp_named_t;

static wmem_map_t *named;      /* tcp_dir_t -> tcp_named_t, file scope */
static GString *kept;          /* the lines not taken yet */
static gboolean listening;

VRSHARK_EXPORT int vrshark_lua_tcp_end_watch(lua_State *L);
VRSHARK_EXPORT int vrshark_lua_tcp_ends(lua_State *L);

static guint
tcp_dir_hash(gconstpointer k)
{
    const tcp_dir_t *d = (const tcp_dir_t *)k;

    return add_address_to_hash(add_address_to_hash((d->src_port << 16) ^ d->dst_port, &d->src), &d->dst);
}

static gboolean
tcp_dir_equal(gconstpointer a, gconstpointer b)
{
    const tcp_dir_t *x = (const tcp_dir_t *)a, *y = (const tcp_dir_t *)b;

    return x->src_port == y->src_port && x->dst_port == y->dst_port && addresses_equal(&x->src, &y->src) &&
           addresses_equal(&x->dst, &y->dst);
}

static void
name_direction(const address *src, const address *dst, guint32 src_port, guint32 dst_port, const char *key,
               gboolean from_client)
{
    tcp_dir_t *d = wmem_new(wmem_file_scope(), tcp_dir_t);
    tcp_named_t *n = wmem_new(wmem_file_scope(), tcp_named_t);

    copy_address_wmem(wmem_file_scope(), &d->src, src);
    copy_address_wmem(wmem_file_scope(), &d->dst, dst);
    d->src_port = src_port;
    d->dst_port = dst_port;
    n->key = key;
    n->from_client = from_client;
    wmem_map_insert(named, d, n);
}

static tap_packet_status
tcp_end_packet(void *tapdata _U_, packet_info *pinfo, epan_dissect_t *edt _U_, const void *data,
               tap_flags_t flags _U_)
{
    const struct tcpheader *th = (const struct tcpheader *)data;
    tcp_dir_t d;
    const tcp_named_t *n;

    if (!th || !(th->th_flags & (TCP_FIN | TCP_RST)) || !named)
        return TAP_PACKET_DONT_REDRAW;
    d.src = pinfo->src;
    d.dst = pinfo->dst;
    d.src_port = pinfo->srcport;
    d.dst_port = pinfo->destport;
    if (!(n = (const tcp_named_t *)wmem_map_lookup(named, &d)))
        return TAP_PACKET_DONT_REDRAW;
    g_string_append_printf(kept, "%s\t%u\t%u\t%.17g\t%d\n", n->key, pinfo->num, (unsigned)th->th_flags,
                           nstime_to_sec(&pinfo->abs_ts), n->from_client ? 1 : 0);
    vrshark_tcp_ends_pending = TRUE;
    return TAP_PACKET_DONT_REDRAW;
}

int
vrshark_lua_tcp_end_watch(lua_State *L)
{
    packet_info *pinfo = vrshark_columns_pinfo();
    const char *key = lua_gettop(L) >= 2 ? lua_tolstring(L, 1, NULL) : NULL;
    const char *port = key ? lua_tolstring(L, 2, NULL) : NULL;
    guint32 client_port;
    gboolean client_is_src;
    char *k;

    if (!pinfo || !key || !port || pinfo->ptype != PT_TCP) {
        lua_pushboolean(L, FALSE);
        return 1;
    }
    if (!listening) {
        GString *err = register_tap_listener("tcp", &listening, NULL, TL_REQUIRES_NOTHING, NULL, tcp_end_packet,
                                             NULL, NULL);

        if (err) {
            g_string_free(err, TRUE);
            lua_pushboolean(L, FALSE);
            return 1;
        }
        kept = g_string_new(NULL);
        listening = TRUE;
    }
    if (!named)
        named = wmem_map_new(wmem_file_scope(), tcp_dir_hash, tcp_dir_equal);
    client_port = (guint32)strtoul(port, NULL, 10);
    client_is_src = pinfo->srcport == client_port;
    k = wmem_strdup(wmem_file_scope(), key);
    name_direction(&pinfo->src, &pinfo->dst, pinfo->srcport, pinfo->destport, k, client_is_src);
    name_direction(&pinfo->dst, &pinfo->src, pinfo->destport, pinfo->srcport, k, !client_is_src);
    lua_pushboolean(L, TRUE);
    return 1;
}

int
vrshark_lua_tcp_ends(lua_State *L)
{
    if (!kept) {
        lua_pushlstring(L, "", 0);
        return 1;
    }
    lua_pushlstring(L, kept->str, kept->len);
    g_string_truncate(kept, 0);
    vrshark_tcp_ends_pending = FALSE;
    return 1;
}

void
vrshark_tcp_ends_reset(void)
{
    /* (the map is the file's: wmem_file_scope() frees it) */
    named = NULL;
    if (kept)
        g_string_truncate(kept, 0);
    vrshark_tcp_ends_pending = FALSE;
}
