"""Where the block diagram draws each block: presentation data by patent numeral.

A box is keyed by the first numeral of its row in the block table
(:data:`allsky.hardware.blocks.BLOCKS`), which gives its name, numerals and
module; an arrow joins two boxes, and the switches written on it are looked
up in the wiring table (:data:`allsky.hardware.wiring.SWITCHES`). Only
positions are typed here, once, so the PNG figure
(:func:`allsky.apps.docgen.block_diagram`) and any other drawing of the
diagram can share them. Units: diagram units, x to the right, y up.
"""

#: Box of a block: first numeral -> (x, y, width, height).
BOXES = {
    "7": (2.6, 8.2, 2.0, 1.1),
    "13": (5.2, 8.2, 2.0, 1.1),
    "1": (0.0, 5.9, 2.0, 1.1),
    "4": (2.6, 5.9, 2.0, 1.1),
    "8": (5.2, 5.9, 2.0, 1.1),
    "14": (7.8, 5.9, 2.0, 1.1),
    "22": (10.8, 5.9, 1.8, 1.1),
    "25": (13.6, 5.9, 2.0, 1.1),
    "28": (16.2, 5.9, 1.8, 1.1),
    "23": (10.3, 8.2, 1.6, 1.1),
    "24": (12.1, 8.2, 1.6, 1.1),
    "21": (13.9, 8.2, 1.6, 1.1),
    "19": (15.7, 8.2, 1.6, 1.1),
    "20": (17.5, 8.2, 1.6, 1.1),
    "120": (2.6, 3.4, 2.0, 1.1),
    "104": (5.2, 3.4, 2.0, 1.1),
    "105": (7.8, 3.4, 2.0, 1.1),
    "31": (11.0, 3.4, 2.0, 1.1),
    "34": (13.6, 3.4, 2.0, 1.1),
    "39": (16.2, 3.4, 1.8, 1.1),
    "100": (0.0, 0.9, 18.0, 1.0),
}
#: Frames around groups of boxes: numeral -> (x, y, width, height).
FRAMES = {"111": (10.0, 5.6, 9.35, 4.1)}
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
    ("28", "31", ((17.1, 5.9), (17.1, 5.05), (12.7, 5.05), (12.7, 4.5)), 1),
    ("104", "31", ((6.2, 4.5), (6.2, 4.85), (12.0, 4.85), (12.0, 4.5)), 1),
    ("4", "31", ((4.3, 5.9), (4.3, 5.3), (11.3, 5.3), (11.3, 4.5)), 1),
    ("24", "22", ((12.9, 8.2), (11.9, 7.0)), 0),
)
#: Lines between the vehicle and the blocks, labelled in words: (from, to, points, text).
VEHICLE_LINES = (
    ("39", "100", ((17.1, 3.4), (17.1, 1.9)), "torque"),
    ("100", "1", ((1.0, 1.9), (1.0, 5.9)), ""),
    ("100", "104", ((6.2, 1.9), (6.2, 3.4)), ""),
    ("100", "105", ((8.8, 1.9), (8.8, 3.4)), ""),
)
#: Figure extent (x min, x max, y min, y max) and size [in].
EXTENT = (-0.3, 19.4, 0.4, 10.2)
FIGSIZE_IN = (15.0, 7.2)
