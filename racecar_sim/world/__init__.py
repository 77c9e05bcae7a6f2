"""What the room holds that the map does not show: unmapped obstacles (boxes, walking people),
furniture along the walls, and the named scenes that place them. Imports the maps and the settings."""
