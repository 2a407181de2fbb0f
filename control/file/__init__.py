"""The trajectory file: its format (columns, units), its parser and its atomic writer."""
