#include <iostream>
int main() { std::cout << "endocast\n"; return 0; }
