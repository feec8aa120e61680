"""rigd package."""
