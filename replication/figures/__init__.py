"""One module per figure. Figure modules draw what they are given; they compute nothing."""

import matplotlib

matplotlib.use("Agg")

FIGURE_DIR = "figures"
