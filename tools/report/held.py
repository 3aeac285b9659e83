"""What a capture holds, in words: the cause a hint names (expect.py) and
the lines of a capture of which no device formed (text.py). Every sentence
follows from the capture's own counts (model.Capture.held): a capture
without UDP gets no hint about UDP ports, frames the snaplen cut get no
port setting that cannot bring them back.
"""

def ids(values):
    return ", ".join("0x%04x" % v for v in values)


def cut(rep, name=None):
    """'29 of 58 frames cut by the capture at 64 bytes (snaplen)', of one
    transport with name, or None when none is cut."""
    held = rep["held"]
    if not held["snaplen"]:
        return None
    if name is None:
        count = sum(held[n]["cut"] for n in ("udp", "pnio_cm", "tcp", "profinet"))
        total = rep["frames"]
        what = "frames"
    else:
        count, total = held[name]["cut"], held[name]["frames"]
        what = {"udp": "UDP frames", "pnio_cm": "PNIO-CM frames", "tcp": "TCP frames", "profinet": "PROFINET frames"}[name]
    if not count:
        return None
    return "%d of %d %s cut by the capture at %d bytes (snaplen)" % (count, total, what, held["snaplen"])


def modbus_cut(rep):
    """TCP frames the snaplen cut: a Modbus/TCP BU's ADUs among them cannot
    be read, and no port setting brings them back."""
    text = cut(rep, "tcp")
    if not text:
        return None
    ports = rep["held"]["tcp"]["cut_ports"]
    return ("the capture cut its Modbus/TCP ADUs: %s%s; no port setting reads them, capture "
            "without a snaplen" % (text, ", on port %s" % ", ".join(map(str, ports)) if ports else ""))


def profinet_undecoded(rep, cause_only=False):
    """PROFINET cyclic frames of which no device and no candidate formed,
    with their count and the cause the capture shows; with cause_only, only
    when it shows one (a cut Connect, frames cut): frames that are whole,
    with their whole capture, and that tshark did not find shaped like ours
    are another device's, as far as the capture tells."""
    pn = rep["held"]["profinet"]
    if not pn["undecoded"]:
        return None
    causes = []
    if pn["connect_cut"]:
        causes.append("the capture cut the Connect in frame %d" % pn["connect_cut"])
    if cut(rep, "profinet"):
        causes.append(cut(rep, "profinet"))
    what = "%d PROFINET cyclic frame%s%s formed no device" % (
        pn["undecoded"], "" if pn["undecoded"] == 1 else "s",
        " (FrameID %s)" % ids(pn["frame_ids"]) if pn["frame_ids"] else "")
    if cause_only and not causes:
        return None
    # (without a cut, what the frames show is their number: few for an excerpt)
    why = " and ".join(causes) if causes else "too few to infer a layout from, or no base's or BU's"
    return "%s: %s; a known layout decodes them: -o mcmb2.layouts, docs/profinet.md" % (what, why)


def no_device(rep):
    """The lines of a capture of which no device formed: what it holds."""
    lines = [line for line in (modbus_cut(rep), profinet_undecoded(rep, cause_only=True)) if line]
    if not lines and not rep["timeline"]:
        return ["no EG-Link, EC-Link or MC-MB2-PN traffic found"]
    lines.insert(0, "no device decoded" + (": tshark's notes in the timeline" if rep["timeline"] else ""))
    return lines
