"""Pictures of wraps."""
