"""Campaigns: many seeded flights (or any independent tasks) on Dask distributed, one results table."""
