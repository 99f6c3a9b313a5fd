"""Annotators: track manifests, proposals, the review page, and clean (manifests applied)."""
