"""Folder-scale conversion: `conversion` (files -> DNGs, size buckets, manifest), `distributed` (Ray)."""
