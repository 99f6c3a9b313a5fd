"""Thin DVC stage entry points: read params, list work items, call pipeline/, write outputs."""

STAGES = ("discover", "download", "propose_segments", "trim", "pose2d", "track", "clean", "train_lifter",
          "train_contact", "lift", "smooth", "resample", "ground", "audio", "shard", "train")
