"""Every tolerance and golden number the tests use, as named constants in one place.

Each section belongs to one area of the code; append new constants to the section they belong to
(or add a section with a header comment). Say in a comment why the value is what it is.
"""

# --- thin-lens optics and cameras (scenes/thin_lens.py, scenes/camera.py) -----------------------
#: Relative agreement between closed forms evaluated two ways (float64 round-off only).
THIN_LENS_RTOL = 1e-12
