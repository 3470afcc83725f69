"""The pivot clamp: grip, impact-point stage, pivot angle encoder."""
