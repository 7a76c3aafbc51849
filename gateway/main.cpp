#include <CLI/CLI.hpp>
int main(int argc, char** argv) {
  CLI::App app{"oegw — CiA 852 operator-environment gateway"};
  CLI11_PARSE(app, argc, argv);
  return 0;
}
