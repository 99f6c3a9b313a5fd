"""Exporters: the corpus laid out as the field's trainers and tools read it (AIST++ for EDGE and
Bailando). They only lay out what the pipeline already made."""
