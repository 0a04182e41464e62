"""The information-limit figure of a comparison: ``python benchmarks/information_limit.py
COMPARE_JSON FIGURE``.

COMPARE_JSON is ``allsky compare --methods legacy,dither,kalman,smoother --json``;
the figure is ``allsky.apps.compare.information_figure`` (docs/comparison.md).
"""

import json
import sys

from allsky.apps.compare import information_figure


def main():
    with open(sys.argv[1]) as f:
        result = json.load(f)
    information_figure(result).savefig(sys.argv[2], dpi=110)
    print(f"wrote {sys.argv[2]}")


if __name__ == "__main__":
    main()
