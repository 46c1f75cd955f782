// Every Asio user includes Asio through this header. Boost 1.74's asio/awaitable.hpp uses
// std::exchange without including <utility>, which GCC 12 in C++20 rejects ("'exchange' is not a
// member of 'std'"); including <utility> first fixes it in one place.
#pragma once

#include <utility>

#include <boost/asio.hpp>
