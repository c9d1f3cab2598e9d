// A shared library named like a plugin but without the entry symbol.
extern "C" __attribute__((visibility("default"))) int qd_something_else() {
  return 42;
}
