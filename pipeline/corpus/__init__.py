"""The corpus: windows, Parquet shards and the dataset card."""
