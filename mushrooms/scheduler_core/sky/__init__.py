"""The sky model: the LVK sky map, ZTF's field grid and footprints, merged cells, and when fields are observable."""
