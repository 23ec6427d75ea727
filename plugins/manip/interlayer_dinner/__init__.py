"""interlayer_dinner: laying out a table for dinner (Dinner-N, Sec. V-C): two rooms, a tray, stacking."""
