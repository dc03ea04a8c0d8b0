"""The plugin layer: pluggy hook specifications, the registry, the spec language that names registered families, and the SDK module plugins import."""

__all__: list[str] = []
