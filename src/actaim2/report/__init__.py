"""Committed result records and the tables of README.md and docs/ regenerated from them
(``actaim2 report``)."""
