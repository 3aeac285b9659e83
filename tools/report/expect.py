"""--expect eglink,eclink,mcmb2: protocols a capture must hold.

A gate that passes on a capture it cannot read (a BU on another port, a base
whose layout is unknown) passes on exactly the captures that need a look:
with --expect such a capture fails the run (exit 1) with one line naming the
protocol and the setting that usually brings its devices back.
"""
from . import held as about

# name: (what the line calls it, the device kinds that are it, where to look when absent)
PROTOCOLS = {
    "eglink": ("EG-Link", {"eglink"}, "EG-Link on another UDP port: -o eglink.input_port:PORT"),
    "eclink": ("EC-Link", {"eclink_modbus", "eclink_pnio"},
               "a Modbus/TCP BU on another port: -o eclink_modbus.port:502,PORT"),
    "mcmb2": ("MC-MB2-PN", {"mcmb2"},
              "a base whose Connect is not in the capture: -o mcmb2.layouts, docs/profinet.md"),
}


def names(text):
    """The protocols of an --expect value; ValueError for an unknown one."""
    found = [n.strip() for n in text.split(",") if n.strip()]
    if not found or any(n not in PROTOCOLS for n in found):
        raise ValueError("%r: a list of %s" % (text, ", ".join(PROTOCOLS)))
    return found


def title(name):
    return PROTOCOLS[name][0]


def missing(rep, expect):
    """The expected protocols of which a readable capture holds no device."""
    if rep["error"]:
        return []
    kinds = {dev["kind"] for dev in rep["devices"]}
    return [name for name in expect if not kinds & PROTOCOLS[name][1]]


def listed(words):
    return ", ".join(words[:-1]) + " and " + words[-1] if len(words) > 1 else words[0]


# Candidates (traffic with the shape of ours that was not recognised) by the
# protocols they may be: a Modbus/TCP server is an EC-Link BU, a PROFINET run
# an MC-MB2-PN base or an EC-Link BU.
CANDIDATE_FOR = {"eclink_modbus.servers": {"eclink"}, "eclink_modbus.port": {"eclink"},
                 "mcmb2.layouts": {"eclink", "mcmb2"}}


def settings(rep, name):
    """The settings that decode the capture's candidates for a protocol."""
    found = []
    for dev in rep["devices"]:
        setting = dev["kind"] == "candidate" and dev.get("address", {}).get("setting")
        if setting and name in CANDIDATE_FOR.get(setting.split(":", 1)[0], ()):
            found.append("-o " + setting)
    return list(dict.fromkeys(found))


def hint(rep, name):
    """Where to look for an absent protocol: the candidates' own settings when
    the capture has candidates for it, else what the capture shows (frames
    cut by the snaplen, PROFINET frames of which no device formed, no frame
    of the transport at all), else the setting that usually helps."""
    found = settings(rep, name)
    if found:
        return "not recognised, to decode: " + ", ".join(found)
    held = rep.get("held")
    if held is None:  # (an unreadable capture's)
        return PROTOCOLS[name][2]
    if name == "eglink":
        if held["udp"]["frames"]:
            return PROTOCOLS[name][2]
        cm = held.get("pnio_cm", {}).get("frames")
        return ("the capture holds no UDP but PROFINET's PNIO-CM (%d frame%s, UDP port 34964)"
                % (cm, "" if cm == 1 else "s") if cm else "the capture holds no UDP (no UDP frame at all)")
    pnio = about.profinet_undecoded(rep)
    if name == "mcmb2":
        if not held["profinet"]["frames"]:
            return "the capture holds no PROFINET cyclic frame"
        return pnio or "its PROFINET frames are all another device's"
    # (no port setting helps a capture without TCP, or one whose ADUs were cut)
    modbus = ("the capture holds no Modbus/TCP (no TCP frame at all)" if not held["tcp"]["frames"]
              else about.modbus_cut(rep) or PROTOCOLS[name][2])
    return "; ".join(filter(None, (modbus, pnio)))


def hints(rep, absent):
    """The hints of the absent protocols, each said once (EC-Link and
    MC-MB2-PN share what the capture shows of PROFINET)."""
    return list(dict.fromkeys(part for n in absent for part in hint(rep, n).split("; ")))


def summary(rep, absent):
    """What is missing and the settings to try: "expected EC-Link, none found
    (19 frames read; not recognised, to decode: -o ...)"."""
    return "expected %s, none found (%d frames read; %s)" % (
        listed([title(n) for n in absent]), rep["frames"], "; ".join(hints(rep, absent)))


def line(rep):
    """The one line for a capture without some expected protocol."""
    return "%s: %s" % (rep["capture"], summary(rep, rep["missing"]))
