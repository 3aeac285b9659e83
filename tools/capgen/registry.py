"""The list of captures: scenario functions register themselves here."""
CAPTURES = {}


def capture(name, description):
    """Register fn() -> pcap.Capture as the generator of captures/<name>."""
    def register(fn):
        if name in CAPTURES:
            raise ValueError("capture %s registered twice" % name)
        fn.description = description
        CAPTURES[name] = fn
        return fn
    return register
