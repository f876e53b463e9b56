// Claims another ABI version: must be refused before anything else is read.
#include <boost/config.hpp>
extern "C" BOOST_SYMBOL_EXPORT int furnihost_abi_version() { return 999; }
