"""Real motion capture in one canonical form: 17 Human3.6M joints and 17 COCO keypoints in metres.

Canonical frame: right-handed, y up, metres. Every loader returns ``MocapSequence``s.
"""
