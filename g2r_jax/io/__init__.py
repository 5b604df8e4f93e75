"""File input and output: DNG tags and pixels, DNG writing, CG image decoding."""
