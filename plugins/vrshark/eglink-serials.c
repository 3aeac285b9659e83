/* eglink-serials.c
 * A sender's serial numbers (twin: lua/vrshark/eglink_serials.luam): in
 * sequence, lost, repeated, or fallen back for a restart; the packets that
 * failed their CRC or size check, whose serials fill a gap without loss; a
 * packet of another header revision, counted but not analysed.
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#include "eglink-shared.h"

#include "eglink-compat.h"

/* A packet of this sender that failed its CRC or size check: not analysed,
 * but its serial, if it holds one, is in the capture. */
void
remember_corrupted(eglink_sender_t *s, packet_info *pinfo, const eglink_info_t *info)
{
    guint i;

    if (!info->has_serial)
        return;
    i = s->n_bad < EGLINK_BAD_SLOTS ? s->n_bad++ : EGLINK_BAD_SLOTS - 1;
    s->bad_frame[i] = pinfo->num;
    s->bad_serial[i] = info->serial;
    s->bad_crc[i] = !info->crc_ok;
}

/* The serials missing before this packet (count of them from expected) that
 * arrived, with a bad CRC or size: no loss, each named on this packet. */
static void
match_corrupted(const eglink_sender_t *s, eglink_frame_t *fd, guint16 expected, guint16 count)
{
    guint i;

    for (i = 0; i < s->n_bad; i++)
        if ((guint16)(s->bad_serial[i] - expected) < count)
            add_finding(fd, FND_CORRUPTED, s->bad_frame[i],
                        s->bad_serial[i] | (s->bad_crc[i] ? EGLINK_CORRUPTED_CRC : 0), 0);
}

/* Packets lost before this one: the serial gap less the packets in it that
 * arrived corrupted. */
guint
serial_lost(const eglink_frame_t *fd, guint16 serial)
{
    const eglink_finding_t *f;
    guint lost;

    if (fd->serial_status != SERIAL_LOST)
        return 0;
    lost = (guint16)(serial - fd->expected_serial);
    for (f = fd->findings; f; f = f->next)
        if (f->kind == FND_CORRUPTED && lost)
            lost--;
    return lost;
}

/* TS-0006 §3.2 numbers a sender's packets sequentially and says nothing of
 * where a sender starts: a serial that falls back a little is a repeat,
 * unless the sender shows that it started again. It does when its periodic
 * packets (VRPI of a BU, VRPO of a controller) stopped for longer than
 * their gap limit, as in a power cycle, or when its VRPI reports BU state
 * Initial ("not fully operative yet", TS-0006 §4.1.1). A BU power-cycled
 * soon after it started falls back by less than the repeat window.
 * input: the packet is the BU's (else its controller's). */
void
track_serial(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info,
             gboolean input)
{
    guint16 serial = info->serial;
    guint16 expected, delta;
    gboolean restarted;

    if (!s->have_serial) {
        fd->serial_status = SERIAL_FIRST;
    } else {
        expected = (guint16)(s->last_serial + 1);
        fd->expected_serial = expected;
        delta = (guint16)(serial - s->last_serial);
        if (delta == 1) {
            fd->serial_status = SERIAL_OK;
        } else if (delta == 0) {
            fd->serial_status = SERIAL_REPEAT;
            add_finding(fd, FND_REPEAT, s->last_serial_frame, s->last_serial, 0);
            return;
        } else if (delta < 0x8000) {
            fd->serial_status = SERIAL_LOST;
            match_corrupted(s, fd, expected, (guint16)(delta - 1));
        } else {
            restarted = (info->type == EGLINK_TYPE_VRPI && info->has_bu_state && info->bu_state == 0x00) ||
                (s->last_periodic_frame && !s->clock_restart &&
                 ns_between(&pinfo->abs_ts, &s->last_periodic_ts) >
                     ms_to_ns(input ? eglink_pref_vrpi_gap_ms : eglink_pref_vrpo_gap_ms));
            if ((guint16)(s->last_serial - serial) <= EGLINK_SERIAL_REPEAT_WINDOW && !restarted) {
                fd->serial_status = SERIAL_REPEAT;
                add_finding(fd, FND_REPEAT, 0, s->last_serial, 0);
                return;
            }
            fd->serial_status = SERIAL_RESTART;
            add_finding(fd, FND_RESTART, 0, s->last_serial, 0);
        }
    }
    s->have_serial = TRUE;
    s->last_serial = serial;
    s->last_serial_frame = pinfo->num;
    s->n_bad = 0;
}

/* TS-0006 5.1.5: a receiver ignores packets with unsupported header values.
 * A packet of another revision (another layout) is kept out of the
 * analysis; its serial is the sender's, so it is counted. */
void
track_revision(eglink_sender_t *s, eglink_frame_t *fd, packet_info *pinfo, const eglink_info_t *info)
{
    fd->flags |= FF_REVISION;
    add_finding(fd, FND_REVISION, 0, info->revision, 0);
    track_serial(s, fd, pinfo, info, eglink_is_input(info->type));
}
