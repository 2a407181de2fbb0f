"""Physical interaction: the wrench a person applies to the platform, from the drives
alone (docs/interaction.md)."""
