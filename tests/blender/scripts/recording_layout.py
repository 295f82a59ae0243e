"""A stand-in for Blender's UILayout that records what a panel draws (a background Blender has no
window to draw into). Standalone on purpose: tests/blender_versions copies it into the chroots
beside version_checks.py, where none of the other scripts are."""


class RecordingLayout:
    """Appends ["label", text] and ["prop", name, value] to ``log``; a property that does not exist
    on its data fails an assert. column() gives the same layout back."""

    def __init__(self, log):
        self.log = log

    def column(self, **_):
        return self

    def label(self, text="", **_):
        self.log.append(["label", text])

    def prop(self, data, prop, **_):
        assert hasattr(data, prop), prop
        self.log.append(["prop", prop, getattr(data, prop)])
