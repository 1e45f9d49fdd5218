"""The comparison interfaces beside the skin: keyboard and teach pendant (docs/interfaces.md)."""
