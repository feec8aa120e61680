"""Importers of recordings made by other rigs and tools into rigd's dataset format (docs/dataset.md)."""
