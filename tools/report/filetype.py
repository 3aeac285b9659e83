"""Is what tshark read a network capture? Decided from tshark's own read.

Wireshark opens some files that are not packet captures at all, each as one
record of a "file format" encapsulation: a 6-byte text file reads as MP4
media, an image or an executable as a MIME file. The report would call such
a file a clean capture without traffic. Every format whose records are
packets (pcap, pcapng, snoop, ERF, 5views, nettl, ...) has a link-layer
encapsulation instead, so the rule is: refuse exactly the file-format
encapsulations below (wiretap's WTAP_ENCAP_* numbers, the same in
Wireshark 4.0 to 4.6), read everything else. It works on a pipe too, where
capinfos cannot look.
"""

# WTAP_ENCAP_*: the file type as capinfos -t names it.
NOT_CAPTURES = {
    134: "MIME File Format (an image, an executable, ...)",   # WTAP_ENCAP_MIME
    175: "JavaScript Object Notation",                          # WTAP_ENCAP_JSON
    201: "Ruby marshal object",                                 # WTAP_ENCAP_RUBY_MARSHAL
    203: "systemd journal",                                     # WTAP_ENCAP_SYSTEMD_JOURNAL
    209: "MP4 media",                                           # WTAP_ENCAP_MP4
}


def refusal(encap):
    """None for a network capture's encapsulation (frame.encap_type as tshark
    prints it), else the one line that says what the file is."""
    try:
        number = int(encap.rsplit(",", 1)[-1], 0)
    except ValueError:
        return None
    kind = NOT_CAPTURES.get(number)
    if kind is None:
        return None
    return "not a network capture: tshark reads it as %s" % kind
