"""Input: touch data, its files and the checks every entry point shares."""
