"""World-frame motion: the root path, gravity and floor, foot contact, one skeleton, joint rotations,
and the grounding that puts them together for the corpus and the BVH export."""
