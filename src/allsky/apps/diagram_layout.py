"""Where the block diagram draws each block: presentation data by patent numeral.

A box is keyed by the first numeral of its row in the block table
(:data:`allsky.hardware.blocks.BLOCKS`), which gives its name, numerals and
module; an arrow joins two boxes, and the switches written on it are looked
up in the wiring table (:data:`allsky.hardware.wiring.SWITCHES`). Only
positions are typed here, once, so the PNG figure
(:func:`allsky.apps.docgen.block_diagram`) and any other drawing of the
diagram can share them. Units: diagram units, x to the right, y up.
"""

#: Box of a block: first numeral -> (x, y, width, height). Three rows of boxes 1.25 high
#: (a title and three value lines at the page's 11 px minimum) above the vehicle's bar.
BOXES = {
    "7": (2.6, 5.75, 2.0, 1.25),
    "13": (5.2, 5.75, 2.0, 1.25),
    "1": (0.0, 3.75, 2.0, 1.25),
    "4": (2.6, 3.75, 2.0, 1.25),
    "8": (5.2, 3.75, 2.0, 1.25),
    "14": (7.8, 3.75, 2.0, 1.25),
    "22": (10.8, 3.75, 1.8, 1.25),
    "25": (13.6, 3.75, 2.0, 1.25),
    "28": (16.2, 3.75, 1.8, 1.25),
    "23": (10.1, 5.75, 1.75, 1.25),
    "24": (11.95, 5.75, 1.75, 1.25),
    "21": (13.8, 5.75, 1.75, 1.25),
    "19": (15.65, 5.75, 1.75, 1.25),
    "20": (17.5, 5.75, 1.75, 1.25),
    "120": (2.6, 1.0, 2.0, 1.25),
    "104": (5.2, 1.0, 2.0, 1.25),
    "105": (7.8, 1.0, 2.0, 1.25),
    "31": (11.0, 1.0, 2.0, 1.25),
    "34": (13.6, 1.0, 2.0, 1.25),
    "39": (16.2, 1.0, 2.0, 1.25),
    "100": (0.0, -0.1, 18.2, 0.6),
}
#: Titles on two lines where one does not fit the box (presentation only).
TWO_LINE_TITLES = {"23": ("Computed", "word 23"), "24": ("Programmed", "word 24"),
                   "21": ("Computer", "seq. 21"), "19": ("Calibration", "seq. 19"),
                   "20": ("Master", "seq. 20")}
#: Frames around groups of boxes: numeral -> (x, y, width, height).
FRAMES = {"111": (10.0, 3.55, 9.35, 3.85)}
#: The vehicle's box (its propellant tank has no numeral of its own).
VEHICLE_BOX = "100"
#: Sensors and the vehicle, drawn shaded.
SHADED = ("1", "104", "105", "100")
#: Straight arrows between boxes: (from, to, route); route "h" joins the facing sides,
#: "v" the facing top and bottom.
ARROWS = (
    ("1", "4", "h"), ("4", "8", "h"), ("8", "14", "h"), ("14", "22", "h"), ("22", "25", "h"),
    ("25", "28", "h"), ("8", "13", "v"), ("13", "7", "h"), ("7", "4", "v"), ("120", "4", "v"),
    ("23", "22", "v"), ("31", "34", "h"), ("34", "39", "h"), ("105", "31", "h"),
)
#: Routed lines: (from, to, points, label index); the last segment carries the arrow
#: head, the switch label is written at ``points[label index]``.
ROUTES = (
    ("28", "31", ((17.1, 3.75), (17.1, 2.95), (12.7, 2.95), (12.7, 2.25)), 1),
    ("104", "31", ((6.2, 2.25), (6.2, 2.65), (12.0, 2.65), (12.0, 2.25)), 1),
    ("4", "31", ((4.3, 3.75), (4.3, 3.3), (11.3, 3.3), (11.3, 2.25)), 1),
    ("24", "22", ((12.8, 5.75), (11.9, 5.0)), 0),
)
#: Lines between the vehicle and the blocks, labelled in words: (from, to, points, text).
VEHICLE_LINES = (
    ("39", "100", ((17.2, 1.0), (17.2, 0.5)), "torque"),
    ("100", "1", ((1.0, 0.5), (1.0, 3.75)), ""),
    ("100", "104", ((6.2, 0.5), (6.2, 1.0)), ""),
    ("100", "105", ((8.8, 0.5), (8.8, 1.0)), ""),
)
#: Figure extent (x min, x max, y min, y max) and size [in].
EXTENT = (-0.3, 19.4, -0.2, 7.55)
FIGSIZE_IN = (15.0, 5.9)

#: What each box does, in plain words, for the page's tooltips (by first numeral).
PLAIN = {
    "1": "Rate gyros 1, 2, 3 measure how fast the vehicle turns about its roll, pitch and "
         "yaw axes.",
    "4": "Summing amplifiers 4, 5, 6 add the gyro rate, the drift correction (S1-S3) and the "
         "rate command (S16, S17).",
    "7": "Drift DACs 7, 9, 11 turn the drift counted in Mode 3 into a rate that cancels the "
         "gyros' drift.",
    "8": "Voltage-to-frequency converters 8, 10, 12 turn each rate into pulses, each pulse a "
         "fixed small angle.",
    "13": "Drift counters 13, 15, 17 count the pulses while the optics hold the vehicle still "
          "(Mode 3): the gyros' drift.",
    "14": "Up/down counters 14, 16, 18 add the pulses up: the angle turned about each axis.",
    "22": "CPU 22 computes the roll, pitch and yaw errors from the counters, register 23 and "
          "register 24 (Mode 6).",
    "25": "Storage registers 25, 26, 27 hold CPU 22's errors for the DACs.",
    "28": "DACs 28, 29, 30 turn the stored errors into the control amplifiers' inputs.",
    "23": "Computed word register 23 holds the calibration: two scale factors and four "
          "cross-coupling factors.",
    "24": "Programmed word register 24 holds the target's roll and yaw angles, computed on "
          "the ground.",
    "21": "Computer sequencer 21 steps selectors S7/S8 through roll, pitch and yaw.",
    "19": "Calibration sequencer 19 reads the counters after each 360 deg turn and writes "
          "register 23.",
    "20": "Master sequencer 20 runs the modes: it waits for each condition and operates the "
          "switches.",
    "120": "Rate-command modules 120 (roll) and 128 (yaw) command a steady turn for Modes 2, "
           "4, 5 and 6.",
    "104": "Sun sensor 104 measures the Sun's angle from the roll axis, in pitch and yaw.",
    "105": "Star tracker 105 measures the star's angle across its slit (roll) and where along "
           "the slit it lies.",
    "31": "Control amplifiers 31, 32, 33 mix the attitude error and the rate into a command.",
    "34": "Pulse-width pulse-frequency modulators 34, 35, 36 turn each command into valve "
          "pulses.",
    "39": "Jet couples 39, 40, 41 fire cold gas to turn the vehicle about each axis.",
    "100": "The vehicle: a rigid body turned by the jets (or wheels); the sensors see its "
           "attitude.",
}
#: The wheel vehicle's actuator box in plain words (it takes the jets' place in the drawing).
PLAIN_WHEELS = ("Reaction wheels take up the control torque; the jets 39-41 fire only to "
                "unload their momentum.")
