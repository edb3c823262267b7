"""The thesis studies as commands: each renders, measures and writes a resumable study folder."""
