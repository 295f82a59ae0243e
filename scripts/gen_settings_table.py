#!/usr/bin/env python3
"""Regenerate the settings table of docs/user-guide.md from addon/schnee_probes/settings.py.

    /usr/bin/python3 scripts/gen_settings_table.py          # rewrite the table in place
    /usr/bin/python3 scripts/gen_settings_table.py --check  # exit 1 if the committed table differs

The table sits between the markers settings.TABLE_BEGIN and settings.TABLE_END;
tests/python/test_settings.py checks that the committed table equals the generated one.
"""
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
GUIDE = REPO / "docs" / "user-guide.md"
sys.path.insert(0, str(REPO / "addon"))

from schnee_probes import settings  # noqa: E402  (plain Python: settings.py needs no bpy)

sys.path.insert(0, str(REPO / "scripts"))
import gen_numbers  # noqa: E402  (the measured figures, from bench/results/*.json)


def render(text):
    """``text`` with the block between the markers replaced by the generated table."""
    begin = text.index(settings.TABLE_BEGIN) + len(settings.TABLE_BEGIN)
    end = text.index(settings.TABLE_END)
    return text[:begin] + "\n" + settings.guide_table(gen_numbers.NUMBERS) + "\n" + text[end:]


def main():
    text = GUIDE.read_text(encoding="utf-8")
    new = render(text)
    if "--check" in sys.argv[1:]:
        if new != text:
            print(f"{GUIDE}: settings table differs from settings.py; run {Path(__file__).name}")
            return 1
        return 0
    if new != text:
        GUIDE.write_text(new, encoding="utf-8")
        print(f"rewrote the settings table in {GUIDE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
