"""``dance3d review``: a local web page for cleaning tracks, over the same CSV manifests."""
