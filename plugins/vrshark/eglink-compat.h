/* eglink-compat.h
 * One source for Wireshark 4.0 through 4.6: the API names and types that
 * changed between those versions.
 *
 * - Write the new names (tvb_get_uint8, tvb_find_uint8,
 *   dissector_try_uint_with_data ...); on older versions they map to the old
 *   ones. The old names are deprecated from 4.4 (4.6 for dissector_try_*),
 *   which -Werror turns into build failures.
 * - Use eglink_heur_bool_t as the result type of a heuristic dissector,
 *   eglink_pref_bool_t for the variable of a boolean preference and
 *   eglink_ret_bool_t for proto_tree_add_item_ret_boolean(): C99 bool on
 *   4.4 and later, gboolean before. CMakeLists.txt tests which one this
 *   Wireshark's headers want (VRSHARK_WS_*_BOOL); without those tests the
 *   version decides.
 * - true_false_string (tfs.h) is no longer included by epan/proto.h from 4.6.
 * - plugin_describe() and wsutil/plugins.h exist from 4.2 on:
 *   EGLINK_HAVE_PLUGIN_DESCRIBE says so (plugin.c).
 *
 * No other file of the plugin compares Wireshark versions or tests the
 * VRSHARK_WS_* results itself (tests/test_eglink_compat.py checks that).
 *
 * SPDX-License-Identifier: GPL-2.0-or-later
 */
#ifndef EGLINK_COMPAT_H
#define EGLINK_COMPAT_H

#include <stdbool.h>
#include <wireshark.h>
#include <ws_version.h>
#include <epan/packet.h>
#include <epan/tfs.h>

#define EGLINK_WS_AT_LEAST(major, minor) \
    (WIRESHARK_VERSION_MAJOR > (major) || \
     (WIRESHARK_VERSION_MAJOR == (major) && WIRESHARK_VERSION_MINOR >= (minor)))

#if !EGLINK_WS_AT_LEAST(4, 4)
#define tvb_get_uint8   tvb_get_guint8
#define tvb_get_int8    tvb_get_gint8
#define tvb_get_uint16  tvb_get_guint16
#define tvb_get_int16   tvb_get_gint16
#define tvb_get_uint24  tvb_get_guint24
#define tvb_get_int24   tvb_get_gint24
#define tvb_get_uint32  tvb_get_guint32
#define tvb_get_int32   tvb_get_gint32
#define tvb_get_uint40  tvb_get_guint40
#define tvb_get_uint48  tvb_get_guint48
#define tvb_get_uint56  tvb_get_guint56
#define tvb_get_uint64  tvb_get_guint64
#define tvb_get_int64   tvb_get_gint64
#define tvb_find_uint8  tvb_find_guint8
#define tvb_find_uint16 tvb_find_guint16
#define tvb_skip_uint8  tvb_skip_guint8
#endif

#if EGLINK_WS_AT_LEAST(4, 2)
#include <wsutil/plugins.h>
#define EGLINK_HAVE_PLUGIN_DESCRIBE 1
#endif

/* A stat_tap_ui init callback (-z) returns bool from 4.6 on, nothing before. */
#if EGLINK_WS_AT_LEAST(4, 6)
#define EGLINK_STAT_INIT_RET bool
#define EGLINK_STAT_INIT_RETURN(ok) return (ok)
#else
#define EGLINK_STAT_INIT_RET void
#define EGLINK_STAT_INIT_RETURN(ok) do { (void)(ok); return; } while (0)
#endif

/* A uint preference's value by module and preference name: 4.6 dropped
 * prefs_get_uint_value(module, name) (the name now reads a pref_t). */
#if EGLINK_WS_AT_LEAST(4, 6)
#include <epan/prefs.h>
#include <epan/prefs-int.h>
static inline unsigned
eglink_prefs_get_uint(const char *module_name, const char *pref_name)
{
    module_t *module = prefs_find_module(module_name);
    pref_t *pref = module ? prefs_find_preference(module, pref_name) : NULL;

    return pref ? prefs_get_uint_value(pref, pref_current) : 0;
}
#else
#include <epan/prefs.h>
#define eglink_prefs_get_uint prefs_get_uint_value
#endif

#if !EGLINK_WS_AT_LEAST(4, 6)
#define dissector_try_uint_with_data    dissector_try_uint_new
#define dissector_try_string_with_data  dissector_try_string_new
#define dissector_try_payload_with_data dissector_try_payload_new
#endif

#ifndef VRSHARK_WS_API_CHECKED
#if EGLINK_WS_AT_LEAST(4, 4)
#define VRSHARK_WS_HEUR_BOOL 1
#define VRSHARK_WS_PREF_BOOL 1
#define VRSHARK_WS_RET_BOOLEAN_BOOL 1
#endif
#endif

#ifdef VRSHARK_WS_HEUR_BOOL
typedef bool eglink_heur_bool_t;
#else
typedef gboolean eglink_heur_bool_t;
#endif

#ifdef VRSHARK_WS_PREF_BOOL
typedef bool eglink_pref_bool_t;
#else
typedef gboolean eglink_pref_bool_t;
#endif

#ifdef VRSHARK_WS_RET_BOOLEAN_BOOL
typedef bool eglink_ret_bool_t;
#else
typedef gboolean eglink_ret_bool_t;
#endif

#endif /* EGLINK_COMPAT_H */
