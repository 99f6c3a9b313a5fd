"""The thin training module (needs the ``train`` extra): stream shards, train a compact
Two-Stream Motion Transformer, sample dance for new music."""
