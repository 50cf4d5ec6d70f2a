"""Thin plot functions, one module per figure (``plot(data, config, out_stem) -> list[Path]``).

The only package that imports matplotlib (Agg backend, set in :mod:`.style`). Plot modules take the
cached compute dict and write ``out_stem.png`` and ``out_stem.pdf`` atomically; they compute nothing
beyond unit conversions.
"""
