// libusb bulk transport for the firmware (interface 0, bulk OUT 0x01, bulk IN 0x81).
#include <libusb.h>

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <string>

#include "firmware_host/driver/firmware_device.h"

namespace hc::fw {
namespace {

std::string hex4(std::uint16_t v) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "%04x", v);
  return buf;
}

std::string usb_error(int rc) { return libusb_error_name(rc); }

Status unavailable(std::string message) {
  return Status(StatusCode::kUnavailable, std::move(message));
}

bool parse_hex16(const std::string& text, std::uint16_t* out) {
  if (text.empty() || text.size() > 4) return false;
  unsigned v = 0;
  for (char c : text) {
    v <<= 4;
    if (c >= '0' && c <= '9')
      v |= static_cast<unsigned>(c - '0');
    else if (c >= 'a' && c <= 'f')
      v |= static_cast<unsigned>(c - 'a' + 10);
    else if (c >= 'A' && c <= 'F')
      v |= static_cast<unsigned>(c - 'A' + 10);
    else
      return false;
  }
  *out = static_cast<std::uint16_t>(v);
  return true;
}

class UsbTransport final : public Transport {
 public:
  UsbTransport(libusb_context* ctx, libusb_device_handle* handle, std::string description)
      : ctx_(ctx), handle_(handle), description_(std::move(description)) {}
  ~UsbTransport() override {
    libusb_release_interface(handle_, kUsbInterface);
    libusb_close(handle_);
    libusb_exit(ctx_);
  }

  Status write(const std::uint8_t* data, std::size_t size) override {
    std::size_t done = 0;
    while (done < size) {
      int transferred = 0;
      const int chunk = static_cast<int>(std::min<std::size_t>(size - done, 4096));
      // libusb takes a non-const buffer for both directions; an OUT transfer does not modify it.
      const int rc =
          libusb_bulk_transfer(handle_, kUsbEndpointOut, const_cast<std::uint8_t*>(data + done),
                               chunk, &transferred, kWriteTimeoutMs);
      if (rc != 0 && rc != LIBUSB_ERROR_TIMEOUT)
        return unavailable("usb write to " + description_ + ": " + usb_error(rc));
      if (rc == LIBUSB_ERROR_TIMEOUT && transferred == 0)
        return Status(StatusCode::kDeadlineExceeded, "usb write to " + description_ + " timed out");
      done += static_cast<std::size_t>(transferred);
    }
    return {};
  }

  Result<std::size_t> read(std::uint8_t* out, std::size_t cap,
                           std::chrono::microseconds timeout) override {
    if (pending_off_ == pending_len_) {
      pending_off_ = pending_len_ = 0;
      int transferred = 0;
      // libusb treats 0 as "wait forever": round a zero timeout up to 1 ms.
      const auto ms = std::max<std::int64_t>(1, (timeout.count() + 999) / 1000);
      // The buffer is a multiple of the 64-byte max packet size so the device can never overflow
      // it.
      const int rc = libusb_bulk_transfer(handle_, kUsbEndpointIn, pending_, sizeof pending_,
                                          &transferred, static_cast<unsigned>(ms));
      if (rc != 0 && rc != LIBUSB_ERROR_TIMEOUT)
        return unavailable("usb read from " + description_ + ": " + usb_error(rc));
      pending_len_ = static_cast<std::size_t>(transferred);
    }
    const std::size_t n = std::min(cap, pending_len_ - pending_off_);
    std::memcpy(out, pending_ + pending_off_, n);
    pending_off_ += n;
    return n;
  }

  std::int64_t now_ns() const override { return host_monotonic_ns(); }
  std::string describe() const override { return description_; }

 private:
  static constexpr unsigned kWriteTimeoutMs = 1000;
  libusb_context* ctx_;
  libusb_device_handle* handle_;
  std::string description_;
  std::uint8_t pending_[16 * 64] = {};
  std::size_t pending_len_ = 0;
  std::size_t pending_off_ = 0;
};

}  // namespace

Result<UsbDeviceSpec> parse_usb_spec(const std::string& spec) {
  UsbDeviceSpec out;
  if (spec == "usb") return out;
  if (spec.rfind("usb:", 0) != 0)
    return invalid_argument("firmware device \"" + spec +
                            "\": expected \"sim\", \"usb\", \"usb:VVVV:PPPP\" or "
                            "\"usb:VVVV:PPPP:SERIAL\"");
  const std::string rest = spec.substr(4);
  const std::size_t c1 = rest.find(':');
  if (c1 == std::string::npos)
    return invalid_argument("firmware device \"" + spec + "\": expected usb:VVVV:PPPP (hex IDs)");
  const std::size_t c2 = rest.find(':', c1 + 1);
  const std::string vid = rest.substr(0, c1);
  const std::string pid =
      rest.substr(c1 + 1, c2 == std::string::npos ? std::string::npos : c2 - c1 - 1);
  if (!parse_hex16(vid, &out.vendor_id))
    return invalid_argument("firmware device \"" + spec + "\": vendor ID \"" + vid +
                            "\" is not 1-4 hex digits");
  if (!parse_hex16(pid, &out.product_id))
    return invalid_argument("firmware device \"" + spec + "\": product ID \"" + pid +
                            "\" is not 1-4 hex digits");
  if (c2 != std::string::npos) {
    out.serial = rest.substr(c2 + 1);
    if (out.serial.empty())
      return invalid_argument("firmware device \"" + spec + "\": empty serial number");
  }
  return out;
}

Result<std::unique_ptr<Transport>> open_usb_transport(const std::string& spec) {
  HC_ASSIGN_OR_RETURN(const UsbDeviceSpec want, parse_usb_spec(spec));
  const std::string ids = hex4(want.vendor_id) + ":" + hex4(want.product_id);
  const std::string wanted =
      "USB device " + ids + (want.serial.empty() ? "" : " with serial \"" + want.serial + "\"");

  libusb_context* ctx = nullptr;
  if (const int rc = libusb_init(&ctx); rc != 0)
    return unavailable("cannot open " + wanted + ": libusb_init failed: " + usb_error(rc));
  libusb_device** list = nullptr;
  const ssize_t count = libusb_get_device_list(ctx, &list);
  if (count < 0) {
    libusb_exit(ctx);
    return unavailable("cannot open " + wanted +
                       ": cannot list USB devices: " + usb_error(static_cast<int>(count)));
  }
  libusb_device_handle* found = nullptr;
  std::string description;
  Status last_error;
  int matches = 0;
  for (ssize_t i = 0; i < count && found == nullptr; ++i) {
    libusb_device_descriptor desc{};
    if (libusb_get_device_descriptor(list[i], &desc) != 0) continue;
    if (desc.idVendor != want.vendor_id || desc.idProduct != want.product_id) continue;
    ++matches;
    libusb_device_handle* handle = nullptr;
    if (const int rc = libusb_open(list[i], &handle); rc != 0) {
      last_error =
          unavailable("cannot open " + wanted + ": libusb_open: " + usb_error(rc) +
                      (rc == LIBUSB_ERROR_ACCESS ? " (add a udev rule granting access)" : ""));
      continue;
    }
    char serial[256] = {};
    if (desc.iSerialNumber != 0)
      libusb_get_string_descriptor_ascii(handle, desc.iSerialNumber,
                                         reinterpret_cast<unsigned char*>(serial), sizeof serial);
    if (!want.serial.empty() && want.serial != serial) {
      libusb_close(handle);
      continue;
    }
    libusb_set_auto_detach_kernel_driver(handle, 1);
    if (const int rc = libusb_claim_interface(handle, kUsbInterface); rc != 0) {
      last_error = unavailable("cannot claim interface 0 of " + wanted + ": " + usb_error(rc));
      libusb_close(handle);
      continue;
    }
    found = handle;
    description = "usb " + ids + " serial=" + serial +
                  " bus=" + std::to_string(libusb_get_bus_number(list[i])) +
                  " address=" + std::to_string(libusb_get_device_address(list[i]));
  }
  libusb_free_device_list(list, 1);
  if (found == nullptr) {
    libusb_exit(ctx);
    if (!last_error.ok()) return last_error;
    return not_found("no firmware " + wanted + " found (" + std::to_string(count) +
                     " USB devices present, " + std::to_string(matches) +
                     " with that vendor:product ID)");
  }
  return std::unique_ptr<Transport>(new UsbTransport(ctx, found, description));
}

}  // namespace hc::fw
