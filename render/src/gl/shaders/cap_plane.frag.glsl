// Caps' depth: nothing but the depth is written (colour writes are off in that pass).
void main() {}
