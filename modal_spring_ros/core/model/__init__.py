"""A scene's data and what it defines: masses, springs, the stiffness matrix, the model."""
