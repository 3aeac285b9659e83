/* eglink-channels.c
 * Where the packets of BUs and controllers meet, and who talks to whom
 * (twin: lua/vrshark/eglink_channels.luam): the channels (a multicast group
 * or unicast address pair, and the BU's input port), the BUs and controllers
 * on each, a packet sent to a wrong port, a controller joined to its BU for
 * being alone with it (and that join withdrawn), and a controller first seen
 * on a port of its own adopted by a BU's channel.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-shared.h"

#include "eglink-compat.h"

#include <epan/to_str.h>

static wmem_map_t *eglink_chans;
static wmem_map_t *eglink_groups;      /* group or address pair (port 0): eglink_group_t */

/* File scope: the BUs and controllers by index. */
wmem_array_t *eglink_bu_by_index;
wmem_array_t *eglink_ctrl_by_index;

void
eglink_channels_init(void)
{
    eglink_bu_by_index = NULL;
    eglink_ctrl_by_index = NULL;
}

static gboolean
address_is_multicast(const address *addr)
{
    const guint8 *d = (const guint8 *)addr->data;

    if (addr->type == AT_IPv4 && addr->len == 4)
        return (d[0] & 0xF0) == 0xE0;
    if (addr->type == AT_IPv6 && addr->len == 16)
        return d[0] == 0xFF;
    return FALSE;
}

static guint
eglink_chan_hash(gconstpointer k)
{
    const eglink_chan_key_t *key = (const eglink_chan_key_t *)k;
    guint h = key->port;

    h = add_address_to_hash(h, &key->a);
    return add_address_to_hash(h, &key->b);
}

static gboolean
eglink_chan_equal(gconstpointer k1, gconstpointer k2)
{
    const eglink_chan_key_t *x = (const eglink_chan_key_t *)k1;
    const eglink_chan_key_t *y = (const eglink_chan_key_t *)k2;

    return x->port == y->port && addresses_equal(&x->a, &y->a) && addresses_equal(&x->b, &y->b);
}

void
eglink_channels_register(void)
{
    eglink_chans = wmem_map_new_autoreset(wmem_epan_scope(), wmem_file_scope(),
                                          eglink_chan_hash, eglink_chan_equal);
    eglink_groups = wmem_map_new_autoreset(wmem_epan_scope(), wmem_file_scope(),
                                           eglink_chan_hash, eglink_chan_equal);
}

/* The key of the channel on this port of the packet's group or address pair. */
static void
eglink_chan_key(packet_info *pinfo, guint32 port, eglink_chan_key_t *key)
{
    key->port = port;
    if (address_is_multicast(&pinfo->dst)) {
        key->a = pinfo->dst;
        clear_address(&key->b);
    } else if (cmp_address(&pinfo->src, &pinfo->dst) <= 0) {
        key->a = pinfo->src;
        key->b = pinfo->dst;
    } else {
        key->a = pinfo->dst;
        key->b = pinfo->src;
    }
}

static eglink_chan_key_t *
eglink_chan_key_copy(const eglink_chan_key_t *key)
{
    eglink_chan_key_t *stored = wmem_new(wmem_file_scope(), eglink_chan_key_t);

    copy_address_wmem(wmem_file_scope(), &stored->a, &key->a);
    copy_address_wmem(wmem_file_scope(), &stored->b, &key->b);
    stored->port = key->port;
    return stored;
}

/* The channels of the packet's group or address pair, on any port. */
static eglink_group_t *
eglink_group(packet_info *pinfo, gboolean create)
{
    eglink_chan_key_t key;
    eglink_group_t *group;

    eglink_chan_key(pinfo, 0, &key);
    group = (eglink_group_t *)wmem_map_lookup(eglink_groups, &key);
    if (!group && create) {
        group = wmem_new0(wmem_file_scope(), eglink_group_t);
        wmem_map_insert(eglink_groups, eglink_chan_key_copy(&key), group);
    }
    return group;
}

/* The channel of the packet's group or address pair on this input port;
 * NULL when there is none and !create. */
static eglink_chan_t *
eglink_chan_find(packet_info *pinfo, guint32 port, gboolean create)
{
    eglink_chan_key_t key;
    eglink_chan_t *chan;
    eglink_group_t *group;

    eglink_chan_key(pinfo, port, &key);
    chan = (eglink_chan_t *)wmem_map_lookup(eglink_chans, &key);
    if (chan || !create)
        return chan;

    chan = wmem_new0(wmem_file_scope(), eglink_chan_t);
    chan->port = port;
    if (key.b.type == AT_NONE)
        chan->where = wmem_strdup_printf(wmem_file_scope(), "%s port %u",
                                         address_to_str(pinfo->pool, &key.a), key.port);
    else
        chan->where = wmem_strdup_printf(wmem_file_scope(), "%s <-> %s port %u",
                                         address_to_str(pinfo->pool, &key.a),
                                         address_to_str(pinfo->pool, &key.b), key.port);
    wmem_map_insert(eglink_chans, eglink_chan_key_copy(&key), chan);
    group = eglink_group(pinfo, TRUE);
    chan->group_next = group->chans;
    group->chans = chan;
    return chan;
}

static gboolean
ctrl_on_chan(const eglink_chan_t *chan, const address *addr)
{
    const eglink_ctrl_t *ctrl;

    for (ctrl = chan->ctrls; ctrl; ctrl = ctrl->next)
        if (addresses_equal(&ctrl->addr, addr))
            return TRUE;
    return FALSE;
}

/* The channel of a controller packet. TS-0006 has the controller send to
 * the BU's input port + 2; a packet it sends to another port (the input
 * port, a wrong one) is still part of its conversation: the channel of its
 * group where it talks to a BU already, or the BU whose input port it went
 * to. *expected is then the port it belongs on (flagged), else 0. A port
 * that is neither (a controller on a port of its own, found by the
 * heuristic) is the output port of a channel of its own. */
eglink_chan_t *
eglink_ctrl_chan(packet_info *pinfo, guint32 *expected)
{
    guint32 port = pinfo->destport;
    guint32 input = port >= 2 ? port - 2 : port;
    eglink_chan_t *chan = eglink_chan_find(pinfo, input, FALSE);
    eglink_chan_t *other;
    eglink_group_t *group;

    *expected = 0;
    if (chan && chan->n_bus)
        return chan;
    group = eglink_group(pinfo, FALSE);
    for (other = group ? group->chans : NULL; other; other = other->group_next) {
        if (other != chan && other->n_bus && ctrl_on_chan(other, &pinfo->src)) {
            *expected = other->port + 2;
            return other;
        }
    }
    other = eglink_chan_find(pinfo, port, FALSE);
    if ((other && other->n_bus) || (!eglink_is_input_port(input) && eglink_is_input_port(port))) {
        *expected = port + 2;
        return other ? other : eglink_chan_find(pinfo, port, TRUE);
    }
    if (!chan)
        chan = eglink_chan_find(pinfo, input, TRUE);
    if (!eglink_is_input_port(input))
        chan->own_port = TRUE;
    return chan;
}

/* The channel of a BU packet: its destination port, the input packet port
 * (TS-0006 2.2). One sent to an input port + 2, the output packet port,
 * belongs to that input port's channel, on the wrong port, as a controller
 * packet sent to the input port does: when a BU is seen there, or that port
 * is a configured input port and this one is not. */
eglink_chan_t *
eglink_bu_chan(packet_info *pinfo, guint32 *expected)
{
    guint32 port = pinfo->destport;
    eglink_chan_t *chan = eglink_chan_find(pinfo, port, FALSE);
    eglink_chan_t *input;

    *expected = 0;
    if (port < 2 || (chan && chan->n_bus) || eglink_is_input_port(port))
        return chan ? chan : eglink_chan_find(pinfo, port, TRUE);
    input = eglink_chan_find(pinfo, port - 2, FALSE);
    if ((input && input->n_bus) || eglink_is_input_port(port - 2)) {
        *expected = port - 2;
        return input ? input : eglink_chan_find(pinfo, port - 2, TRUE);
    }
    return chan ? chan : eglink_chan_find(pinfo, port, TRUE);
}

/* Two BUs with the same origin and address on different ports or groups
 * get the port or group in their name, so that each has its own row in
 * the statistics. */
static const char *
eglink_bu_name(packet_info *pinfo, const eglink_chan_t *chan, guint16 origin)
{
    const char *name = wmem_strdup_printf(wmem_file_scope(), "BU 0x%04x (%s)", origin,
                                          address_to_str(pinfo->pool, &pinfo->src));
    guint i;

    for (i = 0; eglink_bu_by_index && i < wmem_array_get_count(eglink_bu_by_index); i++) {
        const eglink_bu_t *other = *(eglink_bu_t **)wmem_array_index(eglink_bu_by_index, i);
        if (strcmp(other->name, name) == 0)
            return wmem_strdup_printf(wmem_file_scope(), "BU 0x%04x (%s, %s)", origin,
                                      address_to_str(pinfo->pool, &pinfo->src), chan->where);
    }
    return name;
}

/* A BU on one channel has one address. A packet from that address with
 * another origin is the same BU with a new origin (replaced or
 * reconfigured: flagged); one from another address is another BU. */
eglink_bu_t *
eglink_bu_lookup(packet_info *pinfo, eglink_chan_t *chan, guint16 origin)
{
    eglink_bu_t *bu;

    for (bu = chan->bus; bu; bu = bu->next)
        if (addresses_equal(&bu->addr, &pinfo->src))
            return bu;
    bu = wmem_new0(wmem_file_scope(), eglink_bu_t);
    bu->chan = chan;
    bu->origin = origin;
    bu->name = eglink_bu_name(pinfo, chan, origin);
    copy_address_wmem(wmem_file_scope(), &bu->addr, &pinfo->src);
    if (!eglink_bu_by_index)
        eglink_bu_by_index = wmem_array_new(wmem_file_scope(), sizeof(eglink_bu_t *));
    bu->index = wmem_array_get_count(eglink_bu_by_index);
    wmem_array_append_one(eglink_bu_by_index, bu);
    bu->next = chan->bus;
    chan->bus = bu;
    chan->n_bus++;
    return bu;
}

/* A controller whose packets went to a port of its own, where no BU is,
 * and that now turns up on a BU's channel of the same group, or on a BU
 * input port's (an excerpt
 * that starts with a packet it sent to a wrong port): those packets were
 * this conversation's. It moves here, its serials, intervals and commands
 * going on; the second pass shows its earlier packets joined, on the wrong
 * port (show_orphan()). NULL when there is no such controller. */
static eglink_ctrl_t *
eglink_ctrl_adopt(packet_info *pinfo, eglink_chan_t *chan)
{
    eglink_group_t *group = chan->n_bus || !chan->own_port ? eglink_group(pinfo, FALSE) : NULL;
    eglink_chan_t *own;
    eglink_ctrl_t **link, *ctrl;

    for (own = group ? group->chans : NULL; own; own = own->group_next) {
        if (!own->own_port || own->n_bus)
            continue;
        for (link = &own->ctrls; *link; link = &(*link)->next) {
            ctrl = *link;
            if (!addresses_equal(&ctrl->addr, &pinfo->src))
                continue;
            *link = ctrl->next;
            own->n_ctrls--;
            ctrl->next = chan->ctrls;
            chan->ctrls = ctrl;
            chan->n_ctrls++;
            ctrl->chan = chan;
            ctrl->adopted = TRUE;
            return ctrl;
        }
    }
    return NULL;
}

eglink_ctrl_t *
eglink_ctrl_lookup(packet_info *pinfo, eglink_chan_t *chan)
{
    eglink_ctrl_t *ctrl;

    for (ctrl = chan->ctrls; ctrl; ctrl = ctrl->next)
        if (addresses_equal(&ctrl->addr, &pinfo->src))
            return ctrl;
    ctrl = eglink_ctrl_adopt(pinfo, chan);
    if (ctrl)
        return ctrl;
    ctrl = wmem_new0(wmem_file_scope(), eglink_ctrl_t);
    ctrl->chan = chan;
    ctrl->name = wmem_strdup_printf(wmem_file_scope(), "Controller %s (BU not known)",
                                    address_to_str(pinfo->pool, &pinfo->src));
    copy_address_wmem(wmem_file_scope(), &ctrl->addr, &pinfo->src);
    if (!eglink_ctrl_by_index)
        eglink_ctrl_by_index = wmem_array_new(wmem_file_scope(), sizeof(eglink_ctrl_t *));
    ctrl->index = wmem_array_get_count(eglink_ctrl_by_index);
    wmem_array_append_one(eglink_ctrl_by_index, ctrl);
    ctrl->next = chan->ctrls;
    chan->ctrls = ctrl;
    chan->n_ctrls++;
    return ctrl;
}

/* One BU and one controller on a channel belong together (the usual
 * installation, and every single-BU capture). That holds only while they
 * are alone: a second BU or controller on the channel withdraws such a
 * join (noted on this packet), and from then on a controller is joined to
 * its BU only by the commands acknowledged between them. */
void
join_if_alone(eglink_chan_t *chan, eglink_frame_t *fd, packet_info *pinfo)
{
    eglink_ctrl_t *ctrl;

    if (chan->n_bus == 1 && chan->n_ctrls == 1) {
        if (!chan->ctrls->bu)
            chan->ctrls->bu = chan->ctrls->alone_bu = chan->bus;
        return;
    }
    for (ctrl = chan->ctrls; ctrl; ctrl = ctrl->next) {
        if (!ctrl->bu || ctrl->joined_by_ack)
            continue;
        ctrl->bu = NULL;
        ctrl->withdrawn_frame = pinfo->num;
        add_finding(fd, FND_JOIN_WITHDRAWN, 0, ctrl->index, chan->n_bus > 1);
    }
}

/* Several BUs or controllers on one group and port: every controller's
 * VRPO and VRCO reach every BU there. Said once per sender. */
void
check_shared(eglink_chan_t *chan, eglink_sender_t *s, eglink_frame_t *fd)
{
    if (s->shared_reported || (chan->n_bus < 2 && chan->n_ctrls < 2))
        return;
    s->shared_reported = TRUE;
    add_finding(fd, FND_SHARED_GROUP, 0, chan->n_bus, chan->n_ctrls);
}

/* A controller packet joined to its BU only for the two being alone on the
 * channel, when a second BU or controller there withdrew that later: the
 * second pass and the GUI show it as the controller's, its BU not known
 * (or the BU an acknowledgement joined it to later), as its packets after. */
const eglink_frame_t *
frame_view(const eglink_frame_t *fd, eglink_frame_t *buf)
{
    if (!fd->bu || !fd->ctrl || !fd->ctrl->withdrawn_frame)
        return fd;
    *buf = *fd;
    buf->bu = NULL;
    buf->flags &= ~FF_ORIGIN;
    buf->bu_origin = 0;
    return buf;
}
