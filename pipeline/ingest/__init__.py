"""The recipe's first steps: sources, downloads, dance segments, trimming, and the media layer."""
