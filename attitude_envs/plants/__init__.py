"""Plants: equations of motion, free of any Gymnasium machinery."""
