"""What each configuration key means, in which unit, and what it accepts, in words.

The meanings are the comments of the packaged default scenario (the file a
user copies); the unit is read from the key's name suffix; the accepted
values come from the key's rule (:func:`allsky.config.schema.allowed`).
The configuration reference and ``allsky config show`` both read them here.
"""

import functools
import re

from allsky.config.schema import DEFAULT_SCENARIO_PATH, allowed

#: Unit of a key from its name's suffix (longest suffix first).
UNIT_SUFFIXES = (
    ("_v_per_arcsec_s", "V/(arcsec/s)"), ("_v_per_arcsec", "V/arcsec"),
    ("_deg_h_rt_h", "deg/h/sqrt(h)"), ("_deg_rt_h", "deg/sqrt(h)"), ("_deg_h", "deg/h"),
    ("_deg_s", "deg/s"), ("_arcsec", "arcsec"), ("_urad", "urad"), ("_ppm", "ppm"),
    ("_n_m_s", "N m s"), ("_n_m", "N m"), ("_kg_m2", "kg m^2"), ("_m2", "m^2"), ("_km", "km"), ("_kg", "kg"), ("_deg", "deg"), ("_per_s", "1/s"), ("_pps", "pulse/s"),
    ("_frames", "frames"), ("_bits", "bit"), ("_utc", "UTC"), ("_s", "s"), ("_n", "N"),
    ("_m", "m"), ("_v", "V"), ("_bar", "bar"),
)
SPECIAL_UNITS = {"star_tracker.magnitude_window": "mag", "target.ra_deg": "deg",
                 "sequencer.timeout_s": "s"}
#: Meanings of keys the default file leaves unset (so it carries no line for them).
UNSET_KEY_MEANINGS = {
    "target.ra_deg": "target right ascension (J2000), with dec_deg, in place of star",
    "target.dec_deg": "target declination (J2000), with ra_deg, in place of star",
    "target.sequence": ("targets flown one after the other (catalog star names or "
                        "{ ra_deg, dec_deg } tables), in place of star or ra_deg + dec_deg; "
                        "sequencer.between_targets says how the vehicle goes from one to "
                        "the next"),
}
KEY_LINE = re.compile(r"^([A-Za-z_][A-Za-z0-9_]*)\s*=")


def unit_of(key: str) -> str:
    """The unit the name of ``key`` carries (``gyro.drift_deg_h``: deg/h; "-": none)."""
    if key in SPECIAL_UNITS:
        return SPECIAL_UNITS[key]
    name = key.rsplit(".", 1)[1]
    for suffix, unit in UNIT_SUFFIXES:
        if name.endswith(suffix):
            return unit
    return "-"


def key_comments(text: str) -> tuple[dict, dict]:
    """Meaning of each key and intro of each section, from the default file's comments.

    ``text`` is the default scenario file's TOML text. A key's meaning is its
    trailing comment, or the comment lines right above it; comment lines right
    under a section header introduce the section.
    """
    keys, sections = {}, {}
    section, pending, in_value, after_header = None, [], False, False
    for raw in text.splitlines():
        line = raw.strip()
        if in_value:  # continuation lines of a multi-line array
            in_value = line.count("[") > line.count("]") or not line.endswith("]")
            continue
        if line.startswith("[") and line.endswith("]") and "=" not in line:
            section, pending, after_header = line.strip("[]"), [], True
            continue
        if line.startswith("#"):
            pending.append(line.lstrip("#").strip())
            continue
        if after_header and pending:  # the comment right under a header introduces it
            sections[section] = " ".join(pending)
            pending = []
        after_header = False
        if not line:
            pending = []
            continue
        m = KEY_LINE.match(line)
        if m and section:
            value, _, comment = line.partition("#")
            words = comment.strip() or " ".join(pending)
            keys[f"{section}.{m.group(1)}"] = words
            pending = []
            in_value = value.count("[") > value.count("]")
    return keys, sections


@functools.cache
def meanings() -> dict:
    """Key -> meaning, from the default file's comments (and the unset keys')."""
    keys, _ = key_comments(default_text())
    return {**UNSET_KEY_MEANINGS, **keys}


@functools.cache
def default_text() -> str:
    """The packaged default scenario, as text (its comments are the meanings)."""
    return DEFAULT_SCENARIO_PATH.read_text(encoding="utf-8")


def describe(key: str) -> str:
    """One line for ``key``: its meaning, unit and accepted values."""
    unit = unit_of(key)
    unit_text = f" [{unit}]" if unit != "-" else ""
    return f"{meanings().get(key, key)}{unit_text}; accepts: {allowed(key)}"
